"""The whole system: every modality registered on the planes, filtered, tracked and evaluated."""

from ._config import system_params_from_config
from ._outputs import run_to_folder
from ._streams import ModalityReport, camera_evidence, laser_evidence, merged_evidence, sound_evidence
from ._system import SystemParams, SystemResult, evaluate_system, run_system, stack_for_recording, system_laser_model

__all__ = [
    "ModalityReport",
    "SystemParams",
    "SystemResult",
    "camera_evidence",
    "evaluate_system",
    "laser_evidence",
    "merged_evidence",
    "run_system",
    "run_to_folder",
    "sound_evidence",
    "stack_for_recording",
    "system_laser_model",
    "system_params_from_config",
]
