"""aepipe.detect against the rules read sample by sample in NumPy, on a stream made here."""

from __future__ import annotations

import numpy as np
import pytest

import aepipe

FS = 10e6


def rules(x: np.ndarray, thr: float, ddt: int, rearm: int, maxd: int) -> list[tuple[int, int]]:
    """The (first, last) crossing of every hit: the crossings found by NumPy, the rules
    applied crossing by crossing."""
    cross = np.flatnonzero(np.abs(x) >= thr)
    out, i = [], 0
    while i < len(cross):
        first = last = int(cross[i])
        i += 1
        while i < len(cross) and cross[i] <= min(last + ddt, first + maxd - 1):
            last = int(cross[i])
            i += 1
        end = min(last + ddt, first + maxd)
        if end > len(x) - 1:  # still under way when the stream ends
            out.append((first, last))
            break
        out.append((first, last))
        while i < len(cross) and cross[i] <= end + rearm:
            i += 1
    return out


def stream(seed: int) -> np.ndarray:
    rng = np.random.default_rng(seed)
    n = 2_000_000
    x = rng.normal(0, 2e-6, n)
    t = np.arange(1500) / FS
    burst = np.exp(-t / 30e-6) * np.sin(2 * np.pi * 280e3 * t)
    # Bursts every ~2 ms, some pairs 30–400 µs apart, one far beyond the others (clipped
    # to ±5 mV as an ADC would).
    at = np.sort(rng.choice(np.arange(1000, n - 3000, 20_000), 60, replace=False))
    at = np.concatenate([at, at[::5] + rng.integers(300, 4000, len(at[::5]))])
    for k, a in zip(at, rng.uniform(2e-4, 3e-3, len(at))):
        m = min(len(burst), n - k)
        x[k : k + m] += a * burst[:m]
    x[at[7] : at[7] + 1500] = np.clip(x[at[7] : at[7] + 1500] * 10, -5e-3, 5e-3)
    return x.astype(np.float32)


@pytest.mark.parametrize("seed", [1, 2])
def test_detect_cuts_as_the_rules_say(seed: int) -> None:
    x = stream(seed)
    keys = dict(threshold_db=40.0, ddt_s=200e-6, rearm_s=100e-6, max_duration_s=1e-3,
                pretrigger_s=20e-6, posttrigger_s=50e-6)
    hits, waves = aepipe.detect(x, FS, **keys)
    thr = np.float32(1e-6 * 10 ** (40.0 / 20))
    want = rules(x, thr, 2000, 1000, 10_000)
    first = np.rint(hits["time_s"].to_numpy() * FS).astype(int)
    last = first + np.rint(hits["duration_s"].to_numpy() * FS).astype(int)
    assert list(zip(first.tolist(), last.tolist())) == want
    assert (hits["source"] == "detect").all()
    # Each waveform is the stream from 200 samples before the first crossing to 500 after
    # the last (cut at the stream's end).
    for f, l, w in zip(first, last, waves):
        lo, hi = max(f - 200, 0), min(l + 500, len(x) - 1)
        np.testing.assert_array_equal(w, x[lo : hi + 1])
    # The amplitude: the peak |x| within pdt (50 µs) of the first crossing, dB_AE.
    for f, l, a in zip(first, last, hits["amplitude_db"].to_numpy()):
        peak = np.abs(x[f : min(f + 500, l) + 1]).max()
        assert a == pytest.approx(20 * np.log10(peak / 1e-6), abs=1e-4)


def test_two_channels_and_bad_keys() -> None:
    x = stream(3)
    y = np.stack([x, np.roll(x, 50) * 0.5])
    hits, waves = aepipe.detect(y, FS, threshold_db=40.0)
    assert set(hits["channel"].to_list()) == {1, 2}
    assert hits["time_s"].is_sorted()
    assert len(waves) == hits.height
    with pytest.raises(ValueError, match="not \\[detect\\] keys: threshold"):
        aepipe.detect(x, FS, threshold=40.0)
    with pytest.raises(aepipe.ConfigError, match="ddt_s"):
        aepipe.detect(x, FS, ddt_s=-1.0)
