"""Magnitude priors of the unmodelled effects, with their sources.

Units: lengths in mm, angles in rad, compliances in rad/(N mm) (revolute) or mm/N
(prismatic), thermal coefficients in 1/degC, masses in kg.

Every effect of the library carries a *realistic* magnitude (what a healthy machine
shows; the virtual machines draw their truth near it) and a *plausible* bound (the
largest value a machine of that kind can have and still be the machine it claims to
be).  An estimate beyond the plausible bound rejects the candidate: the data ask for
something that is not that effect (``docs/diagnosis.md``, "Magnitude priors").  The
bounds come from catalogues, standards and measurements published for the class of
machine; they are orders of magnitude, chosen generous (a factor 2 to 10 beyond the
catalogue worst case), so that a rejection means "physically wrong", not "unusual".

Sources (cited by key in :data:`PRIORS`):

``harmonic-drive``
    Harmonic Drive AG / Harmonic Drive LLC, component-set catalogues CSF and CSG series:
    "transmission accuracy" (angular transmission error over one output revolution,
    peak to peak) 1 to 2 arcmin (2.9e-4 to 5.8e-4 rad) depending on size; torsional
    stiffness K3 of the order of 1e4 (size 14-20) to 1e6 (size 65-100) N m/rad.
``nabtesco-rv``
    Nabtesco precision reduction gear RV catalogues (RV-N, RV-C series): angular
    transmission error about 1 arcmin, lost motion 1 arcmin or less.
``dumas2011``
    C. Dumas, S. Caro, S. Garnier, B. Furet, "Joint stiffness identification of
    six-revolute industrial serial robots", Robotics and Computer-Integrated
    Manufacturing 27(4), 881-888, 2011: joint stiffnesses of a heavy industrial arm
    (KUKA KR240-2) of the order of 1e6 N m/rad on the main axes and 1e5 on the wrist.
``abele2007``
    E. Abele, M. Weigold, S. Rothenbuecher, "Modeling and identification of an industrial
    robot for machining applications", CIRP Annals 56(1), 387-390, 2007: joint
    stiffnesses of industrial arms in the 1e5 to 1e7 N m/rad range.
``iso3408``
    ISO 3408-3 (ball screws, acceptance conditions) and the makers' tables of lead
    accuracy classes: class C10 (transport) allows 210 um over 300 mm (7e-4); the
    periodic deviation per revolution is specified in micrometres for the positioning
    classes.
``cte``
    W. D. Callister, D. G. Rethwisch, *Materials Science and Engineering*, table of linear
    coefficients of thermal expansion: Invar 1.6e-6, steels 11 to 17e-6, cast iron 10e-6,
    aluminium alloys 23e-6, magnesium 26e-6 /degC; carbon-fibre laminates about 0 (-1 to 2e-6).
``tracker``
    Laser-tracker maximum permissible errors (maker datasheets, e.g. Leica AT960:
    15 um + 6 um/m; evaluated after ASME B89.4.19): a scale error of the order of 1e-5.
``mooring1991``
    B. Mooring, Z. Roth, M. Driels, *Fundamentals of Manipulator Calibration*, Wiley, 1991:
    joint transducer gain (scale) and offset errors; gear ratios are exact integer ratios,
    belt stages and encoder mounting give scale errors of the order of 1e-4.
``iso230``
    ISO 230-1 (test code for machine tools, geometric accuracy: straightness of linear axes,
    tolerances of the order of 0.01 to 0.02 mm per metre of travel) and the linear-guide
    makers' running-parallelism tables (THK LM Guide general catalogue: normal grade of the
    order of 10 to 30 um over one to two metres of rail).
``iso12240``
    ISO 12240-1 (radial spherical plain bearings, radial internal clearance groups C2, normal,
    C3: tens of micrometres for bores of 20 to 50 mm) and ISO 5753-1 (radial internal clearance
    of rolling bearings, group C2 0 to 10 um at bores of 18 to 24 mm).
``weck2006``
    M. Weck, C. Brecher, *Werkzeugmaschinen 5: Messtechnische Untersuchung und Beurteilung*,
    Springer, 2006: static stiffness of machine-tool structures measured at the tool of the order
    of 10 to 100 N/um, i.e. about 1e7 to 1e8 N m/rad for a tilt of the frame with a one-metre lever.

Examples
--------
>>> p = PRIORS["angle-harmonic"]
>>> round(p.plausible, 5), p.unit
(0.00058, 'rad')
>>> stiffness_class(120.0)
'medium'
"""

from __future__ import annotations

from dataclasses import dataclass

__all__ = ["Prior", "PRIORS", "SOURCES", "stiffness_class", "compliance_bounds", "describe_value", "prior_sentence"]


@dataclass(frozen=True)
class Prior:
    """Magnitude prior of one kind of effect parameter.

    Attributes
    ----------
    realistic : float
        Magnitude of a healthy machine (the virtual machines' truth, the screening's scale).
    plausible : float
        Largest plausible absolute value; beyond it the candidate is rejected.
    unit : str
        Unit of both.
    what : str
        Words for the parameter ("gear harmonic", "joint compliance" ...).
    source : str
        Key of :data:`SOURCES` (the citation).
    """

    realistic: float
    plausible: float
    unit: str
    what: str
    source: str


SOURCES = {
    "harmonic-drive": "Harmonic Drive CSF/CSG catalogues: transmission accuracy 1-2 arcmin",
    "nabtesco-rv": "Nabtesco RV catalogues: angular transmission error and lost motion about 1 arcmin",
    "dumas2011": "Dumas et al., RCIM 27(4) 2011: joint stiffness 1e5-1e6 N m/rad on a heavy arm",
    "abele2007": "Abele et al., CIRP Annals 56(1) 2007: joint stiffness 1e5-1e7 N m/rad",
    "iso3408": "ISO 3408-3 ball-screw lead classes: C10 allows 210 µm per 300 mm",
    "cte": "Callister, Materials Science and Engineering: expansion -1e-6 (carbon fibre) to 26e-6 /degC (magnesium)",
    "tracker": "laser-tracker datasheets (e.g. Leica AT960: 15 µm + 6 µm/m)",
    "mooring1991": "Mooring, Roth and Driels, Fundamentals of Manipulator Calibration, 1991",
    "iso230": "ISO 230-1 straightness of linear axes and linear-guide running parallelism (THK: 10-30 um per metre)",
    "iso12240": "ISO 12240-1 / ISO 5753-1 radial internal clearance of spherical plain and rolling bearings",
    "weck2006": "Weck and Brecher, Werkzeugmaschinen 5, 2006: machine frames 10-100 N/um at the tool",
    "assembly": "geometry: a forced defect violated beyond this does not assemble",
}

#: priors per kind of parameter (compliance bounds depend on the robot's size: :func:`compliance_bounds`)
PRIORS = {
    # a strain-wave or cycloidal reducer's periodic error, as an amplitude: the catalogue's worst
    # peak-to-peak transmission error (2 arcmin) taken as amplitude (a factor 2 of margin for wear)
    "angle-harmonic": Prior(1e-4, 5.8e-4, "rad", "gear harmonic", "harmonic-drive"),
    "angle-scale": Prior(2e-4, 5e-3, "1", "transmission-ratio (scale) error", "mooring1991"),
    "backlash-rad": Prior(1.5e-4, 1.5e-3, "rad", "reducer backlash (lost motion)", "nabtesco-rv"),
    "backlash-mm": Prior(0.03, 0.1, "mm", "ball-screw axial clearance", "iso3408"),
    "screw-pitch": Prior(4e-4, 2e-3, "1", "ball-screw lead error", "iso3408"),
    "screw-periodic": Prior(0.01, 0.05, "mm", "ball-screw periodic lead error", "iso3408"),
    "thermal": Prior(1e-5, 3e-5, "1/degC", "structural expansion coefficient", "cte"),
    "leg-thermal": Prior(1.2e-5, 3e-5, "1/degC", "leg expansion coefficient", "cte"),
    "guide-straightness": Prior(0.005, 0.05, "mm", "guide straightness (bow over the stroke)", "iso230"),
    "joint-clearance": Prior(0.01, 0.15, "mm", "platform-joint clearance", "iso12240"),
    # a tilt of the frame under the moment of the moving masses: 5e7 N m/rad realistic, 1e6 N m/rad at the bound
    "base-deformation": Prior(2e-11, 1e-9, "rad/(N mm)", "base tilt compliance (stiffness above 1e6 N m/rad)",
                              "weck2006"),
    "tracker-scale": Prior(1e-5, 1e-4, "1", "tracker scale error", "tracker"),
    "tracker-drift": Prior(0.03, 1.0, "mm", "tracker drift between sessions", "tracker"),
    "compliance-mm": Prior(1e-4, 1e-3, "mm/N", "axis compliance (1 N/um stiffness at the bound)", "abele2007"),
    "violated-rad": Prior(5e-4, 5e-2, "rad", "violated forced defect", "assembly"),
    "violated-mm": Prior(0.05, 2.5, "mm", "violated forced defect", "assembly"),
}

#: smallest plausible joint stiffness (N m/rad) per size class: (main axes, wrist axes).  A
#: factor 10 or more below the smallest value reported for the class ("dumas2011", "abele2007";
#: cobots: "harmonic-drive" stiffness of the sizes they use).
STIFFNESS_FLOOR = {"light": (1e4, 2e3), "medium": (1e5, 1e4), "heavy": (5e5, 5e4)}


def stiffness_class(total_mass_kg: float) -> str:
    """Size class of an arm from the total mass of its moving links (kg).

    ``light`` below 50 kg (collaborative and small arms, payloads up to about 10 kg),
    ``medium`` up to 400 kg (payloads 10 to 100 kg), ``heavy`` above (payloads of 100 kg
    and more).
    """
    if total_mass_kg < 50.0:
        return "light"
    if total_mass_kg <= 400.0:
        return "medium"
    return "heavy"


def compliance_bounds(total_mass_kg: float, wrist: bool) -> tuple[float, str]:
    """Largest plausible revolute joint compliance (rad/(N mm)) for the size class, and the words for it."""
    cls = stiffness_class(total_mass_kg)
    floor = STIFFNESS_FLOOR[cls][1 if wrist else 0]  # N m/rad
    where = "wrist" if wrist else "main-axis"
    return 1.0 / (floor * 1000.0), (f"{where} joint compliance of a {cls} arm ({total_mass_kg:.0f} kg of links): "
                                    f"stiffness above {floor:.0e} N m/rad")


def describe_value(value: float, unit: str) -> str:
    """A value in readable units: angles below 0.1 rad in mrad, lengths below 0.1 mm in µm.

    >>> describe_value(0.0017, "rad")
    '1.7 mrad'
    >>> describe_value(0.04, "mm")
    '40 µm'
    """
    v = abs(value)
    if unit == "rad" and v < 0.1:
        return f"{value * 1e3:.2g} mrad"
    if unit == "mm" and v < 0.1:
        return f"{value * 1e3:.2g} µm"
    return f"{value:.3g} {unit}"


def prior_sentence(name: str, value: float, unit: str, plausible: float, what: str, source: str) -> str:
    """Why an estimate is implausible, e.g. ``1.7 mrad: 2.9x the largest plausible gear harmonic ...``."""
    cite = SOURCES.get(source, source)
    return (f"{name} = {describe_value(value, unit)}: {abs(value) / plausible:.1f}x the largest plausible {what} "
            f"({describe_value(plausible, unit)}; {cite})")
