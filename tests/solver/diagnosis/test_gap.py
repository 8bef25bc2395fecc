"""The gap test's held-out rows: the exact covariance of a fitted model's prediction errors (solver/diagnosis/gap.py).

Units: dimensionless (residuals in units of the stated noise).
"""

from __future__ import annotations

import numpy as np
from scipy.stats import chi2

from hyperstat.solver.diagnosis.gap import _covariance_from


def _refits(x: np.ndarray, xv: np.ndarray, n: int, rng: np.random.Generator) -> np.ndarray:
    """Held-out prediction errors of ``n`` least-squares refits on fresh unit noise (a second method: simulation)."""
    e = rng.standard_normal((n, len(x)))
    ev = rng.standard_normal((n, len(xv)))
    theta = np.linalg.lstsq(x, e.T, rcond=None)[0]  # the fitted parameter error of each draw
    return ev - (xv @ theta).T  # measured minus predicted at the held-out rows


def test_the_prediction_covariance_matches_refits_on_fresh_noise() -> None:
    """A random linear model with 12 parameters from 30 rows; 10 held-out rows, half of them far outside the
    identification rows (extrapolating).  The closed form ``I + xv (x^T x)^-1 xv^T`` matches the covariance of
    20,000 simulated refits within 4 standard errors per entry, and the extrapolating rows' variance is larger
    than the average ``1 + p / n`` that the test used before.  About 0.3 s."""
    rng = np.random.default_rng(7)
    x = rng.standard_normal((30, 12)) * np.logspace(0, 2, 12)  # badly scaled columns, as geometric parameters are
    xv = rng.standard_normal((10, 12)) * np.logspace(0, 2, 12)
    xv[5:] *= 3.0  # far outside the identification rows
    cov = _covariance_from(x, xv)
    r = _refits(x, xv, 20000, rng)
    emp = r.T @ r / len(r)
    se = np.sqrt((cov**2 + np.outer(np.diag(cov), np.diag(cov))) / len(r))  # sd of a Gaussian sample covariance
    assert np.all(np.abs(emp - cov) < 4 * se + 1e-12)
    assert np.diag(cov)[5:].min() > 1 + 12 / 30


def test_the_whitened_held_out_chi_square_has_its_degrees_of_freedom() -> None:
    """Whitened by that covariance, the held-out residuals' chi-square follows chi-square(rows) on 2,000 refits
    (a Kolmogorov-Smirnov distance under 0.05), while dividing by the average inflation ``1 + p / n`` rejects at
    1e-3 far more often than 1e-3 when the held-out rows extrapolate."""
    from scipy.linalg import cho_factor, cho_solve
    from scipy.stats import kstest

    rng = np.random.default_rng(11)
    x = rng.standard_normal((40, 15))
    xv = 2.5 * rng.standard_normal((12, 15))
    cov = _covariance_from(x, xv)
    r = _refits(x, xv, 2000, rng)
    whitened = np.einsum("ij,ij->i", r, cho_solve(cho_factor(cov), r.T).T)
    assert kstest(whitened, chi2(12).cdf).statistic < 0.05
    average = np.sum(r**2, axis=1) / (1 + 15 / 40)
    assert np.mean(chi2.sf(average, 12) < 1e-3) > 0.05
    assert np.mean(chi2.sf(whitened, 12) < 1e-3) < 0.01
