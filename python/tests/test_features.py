"""Features and the CWT, against the command line's tables and a direct NumPy computation."""

from __future__ import annotations

import doctest
import os
import threading
import time
from pathlib import Path

import numpy as np
import polars as pl
import pytest

import aepipe
from conftest import aepipe_cli, feed_fifo, synthetic_signals, wav_folder

IDENTITY = {"experiment", "channel", "hit", "time_s", "source_file"}


def test_features_of_an_array_equal_the_command_lines_table_column_by_column(tmp_path: Path) -> None:
    fs, pre = 10_000_000, 500
    x = synthetic_signals(24, 4096, fs, seed=7)
    folder = wav_folder(tmp_path / "wav", x, fs)
    cfg = tmp_path / "p.toml"
    cfg.write_text(f"[ingest]\npretrigger_samples = {pre}\n")
    out = tmp_path / "out"
    aepipe_cli("features", "--quiet", "--config", cfg, "--out", out, folder)
    theirs = pl.read_parquet(out / "features.parquet")
    ours = aepipe.features(x, sample_rate_hz=fs, pretrigger_samples=pre, config=cfg, threads=1)
    assert theirs.height == ours.height == 24
    assert ours.columns == theirs.columns
    compared = 0
    for c in ours.columns:
        if c in IDENTITY:
            continue
        assert ours[c].to_list() == theirs[c].to_list(), c
        compared += 1
    assert compared > 50
    # A list of 1-D arrays (float64 here) gives the same rows as the 2-D array.
    as_list = aepipe.features([s.astype(np.float64) for s in x], sample_rate_hz=fs, pretrigger_samples=pre, config=cfg)
    assert as_list.equals(ours)
    # The same through paths: exactly the command line's rows, identity included.
    via_paths = aepipe.features(folder, config=cfg)
    assert via_paths.equals(theirs)
    # A labelled mixture: the criteria see both mechanisms.
    assert {"bond_failure", "fibre_failure"} <= set(ours["criteria_label"].to_list())


def morlet_reference(x: np.ndarray, fs: float, f: float, fwhm_periods: float) -> np.ndarray:
    """|W|² by direct time-domain convolution with the analytic Gabor wavelet whose
    spectrum is 2·exp(−(ν − f)²/2σ_f²) (its inverse Fourier transform, sampled)."""
    sigma_f = 2 * np.sqrt(2 * np.log(2)) * f / (2 * np.pi * fwhm_periods)
    sigma_t = 1 / (2 * np.pi * sigma_f)
    half = int(np.ceil(6 * sigma_t * fs))
    t = np.arange(-half, half + 1) / fs
    h = 2 * sigma_f * np.sqrt(2 * np.pi) / fs * np.exp(-(t**2) / (2 * sigma_t**2)) * np.exp(2j * np.pi * f * t)
    w = np.convolve(x.astype(np.float64), h, mode="same")
    return np.abs(w) ** 2


def test_cwt_equals_a_direct_convolution_and_keeps_a_sines_amplitude() -> None:
    fs = 10e6
    x = synthetic_signals(1, 4096, fs, seed=3)[0]
    freqs = [150e3, 250e3, 750e3, 1.2e6]
    p = aepipe.cwt(x, fs, freqs_hz=freqs)
    assert p.shape == (4, 4096) and p.dtype == np.float32
    for k, f in enumerate(freqs):
        ref = morlet_reference(x, fs, f, 2.0)
        m = slice(400, 3700)  # away from the record's ends
        np.testing.assert_allclose(p[k, m], ref[m], rtol=0, atol=2e-3 * ref[m].max())
    # A sine of amplitude A at f: |W| = A inside the record.
    t = np.arange(8192) / fs
    s = (0.3 * np.sin(2 * np.pi * 500e3 * t)).astype(np.float32)
    a = aepipe.cwt(s, fs, freqs_hz=[500e3], power=False)[0]
    np.testing.assert_allclose(a[2000:6000], 0.3, rtol=2e-3)
    # A wider wavelet (4 periods) against the direct convolution too.
    p4 = aepipe.cwt(x, fs, freqs_hz=[400e3], fwhm_periods=4.0)[0]
    ref4 = morlet_reference(x, fs, 400e3, 4.0)
    np.testing.assert_allclose(p4[600:3500], ref4[600:3500], rtol=0, atol=2e-3 * ref4.max())
    # The default grid is the features' (10 … 2 500 kHz, 250 frequencies).
    assert aepipe.cwt(s[:1024], fs).shape == (250, 1024)


@pytest.mark.timeout(120)
def test_a_long_call_releases_the_interpreter(tmp_path: Path) -> None:
    """The job's inputs hold a named pipe that discovery must read, and only another Python
    thread feeds it: the call can end only if it let that thread run. No timing is measured;
    a call that held the interpreter would wait forever, so pytest-timeout's guard ends it at
    120 s and prints every thread's stack into the log."""
    fs = 10_000_000
    wav_folder(tmp_path / "e0", synthetic_signals(4, 4096, fs, seed=11), fs)
    (tmp_path / "gate").mkdir()
    fifo = tmp_path / "gate" / "hit.txt"
    os.mkfifo(fifo)
    stop = threading.Event()
    fed = []
    # A record of 64 samples, one value per line.
    VALUES = "".join(f"{np.sin(0.3 * k) * 1e-3:.6f}\n" for k in range(64)).encode()

    feeder = threading.Thread(target=feed_fifo, args=(fifo, VALUES, stop, fed), daemon=True)
    feeder.start()
    try:
        feats = aepipe.features(tmp_path, threads=1)
    finally:
        stop.set()
    assert fed, "the other thread never ran during the call"
    assert feats.filter(pl.col("experiment") == "gate").height == 1
    assert feats.filter(pl.col("experiment") == "e0").height == 4


def test_progress_draws_a_line_on_stderr(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    fs = 10_000_000
    x = synthetic_signals(600, 4096, fs, seed=5)
    aepipe.features(x, sample_rate_hz=fs, progress=True)
    err = capsys.readouterr().err
    assert "aepipe: 600 signals" in err, err
    folder = wav_folder(tmp_path / "wav", x[:300], fs)
    aepipe.features(folder, progress=True, threads=1)
    err = capsys.readouterr().err
    assert "aepipe: " in err and " records" in err, err
    # Without progress, nothing.
    aepipe.features(x[:3], sample_rate_hz=fs)
    assert capsys.readouterr().err == ""


@pytest.mark.parametrize("module", ["aepipe._features", "aepipe.pickers"])
def test_the_docstring_examples_run(module: str) -> None:
    import importlib

    m = importlib.import_module(module)
    globs = {"aepipe": aepipe, "np": np, "pl": pl}
    r = doctest.testmod(m, extraglobs=globs, optionflags=doctest.ELLIPSIS)
    assert r.failed == 0 and r.attempted > 0, r
