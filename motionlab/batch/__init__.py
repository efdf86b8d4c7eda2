"""Study-scale batch processing: every session of a study manifest, locally or on Dask.

:func:`~motionlab.batch.manifest.load_manifest` reads ``study.yaml``;
:func:`~motionlab.batch.runner.run_study` runs each session as ``motionlab run`` does (skipping
the ones whose inputs are unchanged, isolating failures) and writes the study outputs
(:mod:`~motionlab.batch.outputs`). The CLI is ``motionlab batch``.
"""

from motionlab.batch.manifest import Manifest, SessionSpec, load_manifest
from motionlab.batch.runner import Outcome, Progress, StudyResult, run_study

__all__ = [
    "Manifest",
    "Outcome",
    "Progress",
    "SessionSpec",
    "StudyResult",
    "load_manifest",
    "run_study",
]
