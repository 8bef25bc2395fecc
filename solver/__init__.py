"""hyperstat solver: joint-invariant model, closure, stationarity analysis (numpy/scipy/sympy only).

Units: lengths in mm, angles in rad.
"""

from hyperstat.solver.kinematics.build import MechanismBuilder
from hyperstat.solver.kinematics.closure import AssemblyResult, Kinematics, KinematicState
from hyperstat.solver.errors import (
    AnalysisError,
    AssemblyError,
    DataError,
    HyperstatError,
    ModelError,
    TemplateError,
)
from hyperstat.solver.kinematics.model import (
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
from hyperstat.solver.kinematics.modelfile import dumps_model, load_model, mechanism_from_dict, mechanism_to_dict, save_model
from hyperstat.solver.kinematics.sampling import ConfigurationSample, sample_configurations
from hyperstat.solver.analysis.stationarity import ParameterVerdict, Relation, StationarityResult, analyze, gauge_parameters
from hyperstat.solver.calibration.identify import IdentificationResult, MeasurementModel, identify
from hyperstat.solver.calibration.measurements import MeasurementSet, NoiseModel, read_measurements, write_measurements
from hyperstat.solver.calibration.poses import PoseSelection, select_poses
from hyperstat.solver.calibration.virtual import VirtualMachine
from hyperstat.solver.analysis.symbolic import ExactCheck, exact_check, find_rational_configurations
from hyperstat.solver.analysis.verify import Check, verify

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
