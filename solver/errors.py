"""The project's own error types.

Every error a user can cause carries one sentence that names the input at fault
(a file, a field, a value).  The command line prints that sentence and exits with
code 2; nothing else reaches the user (no traceback).
"""

from __future__ import annotations

__all__ = [
    "HyperstatError",
    "ModelError",
    "AssemblyError",
    "DataError",
    "TemplateError",
    "AnalysisError",
]


class HyperstatError(Exception):
    """Base class of every error hyperstat reports to a user."""


class ModelError(HyperstatError):
    """A mechanism or a model file is malformed; the message names the field."""


class AssemblyError(HyperstatError):
    """The nominal mechanism does not close (assemble) at a requested configuration."""


class DataError(HyperstatError):
    """A measurement, hypothesis or controller file is malformed."""


class TemplateError(HyperstatError):
    """A skeleton template cannot be loaded or built with the given parameters."""


class AnalysisError(HyperstatError):
    """An analysis cannot be carried out on this mechanism (e.g. it cannot move)."""
