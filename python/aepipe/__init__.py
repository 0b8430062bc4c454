"""aepipe from Python: acoustic-emission recordings as Polars frames and NumPy arrays.

The Rust core does the work — the same code as the ``aepipe`` command line — and this layer
only turns arguments into what it takes and its Arrow tables into ``polars.DataFrame``
(through the Arrow C stream interface: no pyarrow needed). Long calls release the GIL,
return on Ctrl-C (``KeyboardInterrupt``) at their next record or simulation, and draw a progress line on
stderr with ``progress=True``. Errors are :class:`AepipeError` subclasses, one per part of
the library, carrying the message the command line prints.

>>> import aepipe
>>> hits = aepipe.read_hits("experiment.pridb")                          # doctest: +SKIP
>>> feats = aepipe.features("experiment.tradb")                          # doctest: +SKIP
>>> som = aepipe.Som().fit(feats, labels="criteria_label")               # doctest: +SKIP
"""

from __future__ import annotations

from . import _aepipe, pickers
from ._aepipe import (
    AepipeError,
    BenchError,
    ClusterError,
    ConfigError,
    FeatureError,
    IngestError,
    MergeError,
    PipelineError,
    PlotError,
    Record,
    ReportError,
    ShardSetError,
    SimError,
    SomError,
    StoreError,
    SynthError,
    TrendError,
    WorkflowError,
)
from ._analysis import Som, trend
from ._cluster import cluster, validity_indices
from ._detect import detect
from ._features import cwt, features
from ._jobs import reference_library, run, simulate
from ._read import iter_waveforms, read_hits, read_waveforms

__version__: str = _aepipe.__version__

__all__ = [
    "AepipeError",
    "BenchError",
    "ClusterError",
    "ConfigError",
    "FeatureError",
    "IngestError",
    "MergeError",
    "PipelineError",
    "PlotError",
    "Record",
    "ReportError",
    "ShardSetError",
    "SimError",
    "Som",
    "SomError",
    "StoreError",
    "SynthError",
    "TrendError",
    "WorkflowError",
    "cluster",
    "cwt",
    "detect",
    "features",
    "iter_waveforms",
    "pickers",
    "read_hits",
    "read_waveforms",
    "reference_library",
    "run",
    "simulate",
    "trend",
    "validity_indices",
]
