"""Arrival-time pickers with vallenae's signatures and results.

Each returns ``(values, index)``: the picker's detection function over the whole signal and
the index of the arrival it picks, exactly as ``vallenae.timepicker`` (0.14) computes them —
squares in the signal's float32, sums in float64 — so the index is vallenae's to the sample.
The signal is taken as float32 (as recorded samples are); the work is aepipe's Rust core,
O(n) with prefix sums.

>>> import numpy as np
>>> from aepipe import pickers
>>> x = np.zeros(1000, np.float32); x[400:] = np.sin(np.arange(600) * 0.3)
>>> pickers.aic(x)[1], pickers.hinkley(x)[1]
(400, 400)
"""

from __future__ import annotations

import numpy as np

from . import _aepipe
from ._common import f32_1d

__all__ = ["aic", "energy_ratio", "hinkley", "modified_energy_ratio"]


def hinkley(arr: np.ndarray, alpha: float = 5) -> tuple[np.ndarray, int]:
    """Hinkley criterion: the partial energy minus a trend of total/(alpha·n) per sample
    (float64 values); the pick is the first index of its minimum.

    >>> vals, i = pickers.hinkley(x, alpha=5)   # doctest: +SKIP
    """
    return _aepipe.pick_hinkley(f32_1d(arr), float(alpha))


def aic(arr: np.ndarray) -> tuple[np.ndarray, int]:
    """Akaike information criterion of the two-segment model (float64 values, the last one
    NaN); the pick is the first index of its minimum. Needs at least 2 samples.

    >>> vals, i = pickers.aic(x)                # doctest: +SKIP
    """
    return _aepipe.pick_aic(f32_1d(arr))


def energy_ratio(arr: np.ndarray, win_len: int = 100) -> tuple[np.ndarray, int]:
    """Energy of the ``win_len`` samples after each sample over those before it (float32
    values, 0 within ``win_len`` of either end); the pick is the first index of its maximum.

    >>> vals, i = pickers.energy_ratio(x, win_len=100)   # doctest: +SKIP
    """
    return _aepipe.pick_energy_ratio(f32_1d(arr), int(win_len), False)


def modified_energy_ratio(arr: np.ndarray, win_len: int = 100) -> tuple[np.ndarray, int]:
    """(energy ratio · |x|) to the fourth power, as vallenae computes it (float32 values);
    the pick is the first index of its maximum.

    >>> vals, i = pickers.modified_energy_ratio(x)       # doctest: +SKIP
    """
    return _aepipe.pick_energy_ratio(f32_1d(arr), int(win_len), True)
