"""`fitode batch`: fit many videos listed in a manifest, on a local process pool or a Ray cluster.

    from fitode.batch import run_batch
    result = run_batch("videos.csv", workers=4)
    result.rows        # one SummaryRow per video, in manifest order
    result.aggregate   # per setting: mean and std over its videos of every constant

See fitode.batch.manifest for the manifest format (CSV or TOML) and fitode.batch.runner for how
a batch resumes.
"""
from .executors import LocalExecutor, RayExecutor, available_cpus, make_executor
from .job import JobOutcome, Task, execute_job
from .manifest import Job, Manifest, ManifestError, load_manifest
from .runner import BatchResult, default_out_dir, run_batch
from .summary import SummaryRow, format_aggregate

__all__ = ["BatchResult", "Job", "JobOutcome", "LocalExecutor", "Manifest", "ManifestError", "RayExecutor",
           "SummaryRow", "Task", "available_cpus", "default_out_dir", "execute_job", "format_aggregate",
           "load_manifest", "make_executor", "run_batch"]
