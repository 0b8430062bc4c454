"""The per-hit method: feature rows of files or arrays, and the CWT of one signal."""

from __future__ import annotations

import warnings
from typing import Sequence, Union

import numpy as np
import polars as pl

from . import _aepipe
from ._common import Paths, PathLike, config_arg, f32_1d, is_paths, paths_arg

Signals = Union[np.ndarray, Sequence[np.ndarray]]


def features(
    data: Paths | Signals,
    *,
    sample_rate_hz: float | None = None,
    pretrigger_samples: int = 0,
    config: PathLike | None = None,
    threads: int | None = None,
    progress: bool = False,
) -> pl.DataFrame:
    """The feature rows (``features.parquet``'s columns): hit features, the power spectrum's
    25 power ratios (Eq. 4.5.4), the 200 time/frequency bins of the CWT (ch. 5.2), the
    ch. 4.7 criteria label and quality check, and the four pickers' onsets.

    ``data`` is paths (files or folders; the rows are then exactly what ``aepipe features``
    writes, rejects named in a warning), a 2-D array of signals (one per row) or a list of
    1-D arrays. For arrays ``sample_rate_hz`` is needed and ``pretrigger_samples`` says
    where the trigger is; the rows are experiment ``"array"``, channel 1, hit = position + 1,
    and samples are volts, computed in float32 as the command line does. ``threads``
    defaults to all cores.

    >>> import numpy as np, aepipe
    >>> x = np.random.default_rng(1).normal(0, 1e-4, (10, 4096)).astype(np.float32)
    >>> f = aepipe.features(x, sample_rate_hz=10e6, pretrigger_samples=500)
    >>> f.height, f["tf_bins"].dtype.size
    (10, 200)
    """
    if not is_paths(data):
        if sample_rate_hz is None:
            raise ValueError("sample_rate_hz is needed for signals given as arrays")
        if isinstance(data, np.ndarray):
            if data.ndim == 1:
                data = data[np.newaxis, :]
            if data.ndim != 2:
                raise ValueError(f"expected a 2-D array of signals, got {data.ndim}-D")
            rows = list(np.ascontiguousarray(data, dtype=np.float32))
        else:
            rows = [f32_1d(r) for r in data]
            if not rows:
                raise ValueError("no signals given")
        stream = _aepipe.features_of_signals(
            rows, float(sample_rate_hz), int(pretrigger_samples), config_arg(config), threads, progress
        )
        return pl.DataFrame(stream)
    feats, rejects = _aepipe.features_of_paths(paths_arg(data), config_arg(config), threads, progress)
    rej = pl.DataFrame(rejects)
    if rej.height:
        r = rej.row(0, named=True)
        warnings.warn(
            f"aepipe: {rej.height} record(s) rejected; first: {r['source_file']} "
            f"{r['record_id']} [{r['stage']}]: {r['reason']}",
            stacklevel=2,
        )
    return pl.DataFrame(feats)


def cwt(
    x: np.ndarray,
    sample_rate_hz: float,
    *,
    freqs_hz: Sequence[float] | np.ndarray | None = None,
    fwhm_periods: float = 2.0,
    power: bool = True,
) -> np.ndarray:
    """The continuous wavelet transform of one signal at full resolution: |W(t, f)|²
    (``power=False``: |W|) as a float32 array of frequencies × samples.

    The wavelet is aepipe's Gabor (Morlet) wavelet, a complex exponential under a Gaussian
    ``fwhm_periods`` periods wide at half maximum, normalised so that a sine of amplitude A
    gives |W| = A; ``freqs_hz`` defaults to the feature grid (10 … 2 500 kHz, 250
    frequencies). The same engine computes the features' bins. Rows are computed on a shorter
    transform and interpolated along time, or interpolated across frequency between exact
    rows, where that is cheaper: within 5e-5 of the scalogram's peak (and 1e-4 of each row's
    peak on broadband signals) of one full-length inverse FFT per frequency.

    >>> t = np.arange(4096) / 10e6
    >>> p = aepipe.cwt(0.3 * np.sin(2 * np.pi * 250e3 * t), 10e6, freqs_hz=[250e3, 750e3])
    >>> p.shape, round(float(np.sqrt(p[0, 2048])), 2)
    ((2, 4096), 0.3)
    """
    a = f32_1d(x)
    f = None if freqs_hz is None else [float(v) for v in np.asarray(freqs_hz).ravel()]
    return _aepipe.cwt(a, float(sample_rate_hz), f, float(fwhm_periods), bool(power))
