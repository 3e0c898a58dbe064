"""The whole system: every modality registered on the planes, filtered, tracked and evaluated."""

from ._outputs import run_plan, run_to_folder, write_presentation
from ._plan import RunPlan, resume_key
from ._streams import (
    EvidenceSource,
    MergedEvidence,
    ModalityReport,
    camera_evidence,
    camera_source,
    laser_evidence,
    laser_sources,
    merged_evidence,
    sound_evidence,
    sound_sources,
)
from ._system import (
    SystemParams,
    SystemResult,
    SystemRun,
    evaluate_system,
    run_system,
    stack_for_recording,
    system_laser_model,
)

__all__ = [
    "EvidenceSource",
    "MergedEvidence",
    "ModalityReport",
    "SystemParams",
    "SystemResult",
    "SystemRun",
    "camera_evidence",
    "camera_source",
    "evaluate_system",
    "laser_evidence",
    "laser_sources",
    "merged_evidence",
    "RunPlan",
    "resume_key",
    "run_plan",
    "run_system",
    "run_to_folder",
    "sound_evidence",
    "sound_sources",
    "stack_for_recording",
    "system_laser_model",
    "write_presentation",
]
