"""hyperstat solver: joint-invariant model, closure, stationarity analysis (numpy/scipy/sympy only).

Units: lengths in mm, angles in rad.
"""

from .build import MechanismBuilder
from .closure import AssemblyResult, Kinematics, KinematicState
from .errors import (
    AnalysisError,
    AssemblyError,
    DataError,
    HyperstatError,
    ModelError,
    TemplateError,
)
from .model import (
    Chain,
    ConfigurationFrame,
    Defect,
    FixedTransform,
    Joint,
    Mechanism,
    ParameterInfo,
    Placement,
    full_defects,
)
from .modelfile import dumps_model, load_model, mechanism_from_dict, mechanism_to_dict, save_model
from .sampling import ConfigurationSample, sample_configurations
from .stationarity import ParameterVerdict, Relation, StationarityResult, analyze, gauge_parameters
from .identify import IdentificationResult, MeasurementModel, identify
from .measurements import MeasurementSet, NoiseModel, read_measurements, write_measurements
from .poses import PoseSelection, select_poses
from .virtual import VirtualMachine
from .symbolic import ExactCheck, exact_check, find_rational_configurations
from .verify import Check, verify

__all__ = [
    "MechanismBuilder",
    "AssemblyResult",
    "Kinematics",
    "KinematicState",
    "AnalysisError",
    "AssemblyError",
    "DataError",
    "HyperstatError",
    "ModelError",
    "TemplateError",
    "Chain",
    "ConfigurationFrame",
    "Defect",
    "FixedTransform",
    "Joint",
    "Mechanism",
    "ParameterInfo",
    "Placement",
    "full_defects",
    "dumps_model",
    "load_model",
    "mechanism_from_dict",
    "mechanism_to_dict",
    "save_model",
    "ConfigurationSample",
    "sample_configurations",
    "ParameterVerdict",
    "Relation",
    "StationarityResult",
    "analyze",
    "gauge_parameters",
    "ExactCheck",
    "exact_check",
    "find_rational_configurations",
    "Check",
    "verify",
    "IdentificationResult",
    "MeasurementModel",
    "identify",
    "MeasurementSet",
    "NoiseModel",
    "read_measurements",
    "write_measurements",
    "PoseSelection",
    "select_poses",
    "VirtualMachine",
]
