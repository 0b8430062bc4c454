"""Cutting a continuous recording into hits, as ``[detect]`` does for stream files."""

from __future__ import annotations

from typing import Sequence, Union

import numpy as np
import polars as pl

from . import _aepipe
from ._common import f32_1d

Channels = Union[np.ndarray, Sequence[np.ndarray]]

#: The ``[detect]`` keys ``detect`` takes (``docs/formats.md``, "Continuous recordings").
KEYS = (
    "mode",
    "auto_min_samples",
    "threshold_db",
    "floating",
    "floating_factor",
    "floating_window_s",
    "ddt_s",
    "rearm_s",
    "max_duration_s",
    "pdt_s",
    "pretrigger_s",
    "posttrigger_s",
    "split_gap_s",
    "block_samples",
)


def _toml_value(v: object) -> str:
    if isinstance(v, bool):
        return "true" if v else "false"
    if isinstance(v, str):
        return '"' + v.replace("\\", "\\\\").replace('"', '\\"') + '"'
    if isinstance(v, (int, float, np.integer, np.floating)):
        return repr(float(v)) if isinstance(v, (float, np.floating)) else str(int(v))
    raise TypeError(f"a [detect] value must be a number, bool or string, got {type(v).__name__}")


def detect(
    x: Channels, sample_rate_hz: float, **keys: object
) -> tuple[pl.DataFrame, list[np.ndarray]]:
    """Cut a stream into hits the way an acquisition system does: a hit starts at the first
    sample with ``|x| ≥ threshold``, goes on while crossings come within ``ddt_s`` (and
    before ``max_duration_s``), and the detector is blind for ``rearm_s`` after it; each
    hit keeps ``pretrigger_s`` before its first crossing and ``posttrigger_s`` after its
    last. ``keys`` are ``[detect]``'s (``threshold_db=40.0``, ``ddt_s=200e-6``, …; ``mode``
    is ``"on"``).

    ``x`` is volts: a 1-D array (one channel), a 2-D array (channels × samples) or a list
    of 1-D arrays; channel k is ``k + 1``. Returns the hits frame (``hits.parquet``'s
    columns, ``source = "detect"``, ``time_s`` from the stream's first sample, in order of
    first crossing) and each hit's waveform, volts, in the same order.

    >>> import numpy as np, aepipe
    >>> x = np.zeros(100_000, np.float32); x[20_000:20_050] = 1e-3
    >>> hits, waves = aepipe.detect(x, 10e6, threshold_db=40.0)
    >>> hits.height, round(hits["time_s"][0], 6)
    (1, 0.002)
    """
    unknown = sorted(set(keys) - set(KEYS))
    if unknown:
        raise ValueError(f"not [detect] keys: {', '.join(unknown)} (known: {', '.join(KEYS)})")
    if isinstance(x, np.ndarray):
        if x.ndim == 1:
            x = x[np.newaxis, :]
        if x.ndim != 2:
            raise ValueError(f"expected 1-D or channels × samples, got {x.ndim}-D")
        chans = [np.ascontiguousarray(c, dtype=np.float32) for c in x]
    else:
        chans = [f32_1d(c) for c in x]
    settings = {"mode": "on", **keys}
    text = "[detect]\n" + "".join(f"{k} = {_toml_value(v)}\n" for k, v in settings.items())
    stream, waves = _aepipe.detect(chans, float(sample_rate_hz), text)
    return pl.DataFrame(stream), list(waves)
