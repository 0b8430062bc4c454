"""Whole jobs from Python — simulation, reference library, the run — against the command
line, and what a long call does on Ctrl-C."""

from __future__ import annotations

import _thread
import faulthandler
import glob
import os
import tempfile
import threading
import time
from pathlib import Path

import polars as pl
import pytest

import aepipe
from conftest import ROOT, aepipe_cli, feed_fifo, synthetic_signals, wav_folder


def test_simulate_equals_the_command_lines_waveforms(tmp_path: Path) -> None:
    ours = aepipe.simulate("structure2x1-fibre-failure", point=7, iterations=3000)
    aepipe_cli("simulate", "--scenario", "structure2x1-fibre-failure", "--param", "point=7", "--param", "iterations=3000", "--out", tmp_path)
    theirs = pl.read_parquet(tmp_path / "waveforms.parquet")
    assert ours.height == theirs.height == 2
    assert ours.drop("source_file").equals(theirs.drop("source_file"))
    assert ours["label"].to_list() == ["fibre_failure"] * 2
    # A model file is a scenario too (Appendix-A sections or TOML).
    with pytest.raises(aepipe.SimError, match="unknown scenario"):
        aepipe.simulate("no-such-scenario")
    # A parameter the scenario does not read is a typo, refused by name.
    with pytest.raises(aepipe.SimError, match="no parameter pint"):
        aepipe.simulate("structure2x1-fibre-failure", pint=7)


def test_reference_library_equals_the_command_lines(tmp_path: Path) -> None:
    toml = tmp_path / "lib.toml"
    toml.write_text(
        "[reference]\nseed = 11\nvariants = 1\nsensors = [[125, 100]]\n"
        '[[reference.scenario]]\nname = "mesh3x3-bond-failure"\n'
        "params = { stretch = [0.009, 0.011], iterations = [3000] }\nerroneous = 2\n"
        '[[reference.scenario]]\nname = "structure2x1-fibre-failure"\n'
        "params = { point = [3, 7], iterations = [3000] }\n"
    )
    ours = aepipe.reference_library(toml, threads=2)
    aepipe_cli("reference", "--config", toml, "--out", tmp_path / "lib", "--threads", "1")
    theirs = pl.read_parquet(tmp_path / "lib" / "waveforms.parquet")
    assert ours.equals(theirs)
    labels = ours.group_by("label").len().sort("label")
    assert dict(labels.iter_rows()) == {"bond_failure": 2, "erroneous": 4, "fibre_failure": 2}


def test_run_gives_the_command_lines_tables_and_a_summary(tmp_path: Path) -> None:
    fs = 10_000_000
    folder = wav_folder(tmp_path / "wav", synthetic_signals(90, 4096, fs, seed=4), fs)
    cfg = tmp_path / "run.toml"
    cfg.write_text(
        "[ingest]\npretrigger_samples = 500\n"
        '[trend]\ncutoff = "none"\n'
        '[som]\ntrain_on = "criteria"\nrows = 5\ncols = 5\n'
    )
    s = aepipe.run(cfg, folder, tmp_path / "py")
    aepipe_cli("run", "--config", cfg, folder, "--out", tmp_path / "cli")
    assert Path(s["report"]).is_file() and s["report"].endswith("report.html")
    assert s["counts"]["feature_rows"] == 90 and s["counts"]["rejects"] == 0
    for name in ("features", "hits", "trend", "classification", "damage_profile"):
        p = Path(s["tables"][name])
        assert p.is_file(), name
        rel = p.relative_to(tmp_path / "py")
        assert pl.read_parquet(p).equals(pl.read_parquet(tmp_path / "cli" / rel)), name
    assert sum(s["som"]["classes"].values()) == 90
    assert s["headline"][0].startswith("hits: 90 read")
    assert {"features", "trend", "som training", "classification", "damage profile", "report"} <= set(s["seconds"])
    assert set(s["peak_rss_bytes"]) == set(s["seconds"])


def test_a_long_call_returns_on_ctrl_c_and_cleans_up(tmp_path: Path) -> None:
    """Each job interrupted here is one that cannot finish first, whatever the machine: a
    library of 2 048 simulations (the embedded one is 64), and a feature run that waits on
    an input the test releases only after the interrupt. That the call raises
    KeyboardInterrupt, after the interrupt was sent, is what is checked; no duration is
    asserted on a shared machine. A call that ignored the request would run for many
    minutes: a guard ends the test process after HANG_GUARD_S, naming where it hung."""
    faulthandler.dump_traceback_later(HANG_GUARD_S, exit=True)
    try:
        _interrupt_two_jobs(tmp_path)
    finally:
        faulthandler.cancel_dump_traceback_later()


#: Far above what an interrupted call takes (well under a second here), far below what the
#: jobs take uninterrupted.
HANG_GUARD_S = 120


def _interrupt_two_jobs(tmp_path: Path) -> None:

    def interrupt_later(delay: float, at: list[float], then=None) -> None:
        time.sleep(delay)
        at.append(time.perf_counter())
        _thread.interrupt_main()
        if then is not None:
            then()

    leftovers = lambda: glob.glob(os.path.join(tempfile.gettempdir(), f"aepipe-py-{os.getpid()}-*"))  # noqa: E731
    # The embedded library with 32 times its material draws: 2 048 simulations of 6 000
    # steps cannot be done in half a second by any build.
    lib = (ROOT / "pipelines" / "reference-library.toml").read_text()
    assert "variants = 4\n" in lib
    big = tmp_path / "big-library.toml"
    big.write_text(lib.replace("variants = 4\n", "variants = 128\n"))
    at: list[float] = []
    threading.Thread(target=interrupt_later, args=(0.5, at), daemon=True).start()
    with pytest.raises(KeyboardInterrupt):
        aepipe.reference_library(big, threads=2)
    assert len(at) == 1, "the call returned before the interrupt was sent"
    # The job stopped (its next simulation saw the request) and its folder is gone.
    deadline = time.time() + 20
    while leftovers() and time.time() < deadline:
        time.sleep(0.2)
    assert not leftovers()
    # The feature pipeline stops too. Its inputs hold a named pipe, which discovery must
    # read: the job waits there until the interrupt has been sent, then the pipe is fed (as
    # often as it is opened) and the job's next record sees the request.
    fs = 10_000_000
    with tempfile.TemporaryDirectory() as d:
        wav_folder(Path(d) / "e0", synthetic_signals(40, 4096, fs, seed=1), fs)
        (Path(d) / "gate").mkdir()
        fifo = Path(d) / "gate" / "hit.txt"
        os.mkfifo(fifo)
        stop = threading.Event()
        values = "".join(f"{0.1 * (k % 7) - 0.3:.2f}\n" for k in range(64)).encode()
        feeder = threading.Thread(target=feed_fifo, args=(fifo, values, stop), daemon=True)
        at.clear()
        threading.Thread(target=interrupt_later, args=(0.3, at, feeder.start), daemon=True).start()
        try:
            with pytest.raises(KeyboardInterrupt):
                aepipe.features(d, threads=1)
            assert len(at) == 1, "the call returned before the interrupt was sent"
            deadline = time.time() + 10
            while leftovers() and time.time() < deadline:
                time.sleep(0.2)
            assert not leftovers()
        finally:
            stop.set()


def test_bad_inputs_raise_typed_errors(tmp_path: Path) -> None:
    import numpy as np

    with pytest.raises(aepipe.IngestError, match="no such file"):
        aepipe.read_hits(tmp_path / "missing.pridb")
    bad = tmp_path / "bad.toml"
    bad.write_text("[dsp]\nband_hz = -1\n")
    with pytest.raises(aepipe.ConfigError, match="band_hz"):
        aepipe.features(np.zeros((1, 64), np.float32), sample_rate_hz=1e6, config=bad)
    with pytest.raises(aepipe.ConfigError):
        aepipe.read_hits(tmp_path, config=tmp_path / "absent.toml")
    x = np.zeros((2, 256), np.float32)
    x[1, 7] = np.nan
    with pytest.raises(aepipe.FeatureError, match="signal 1"):
        aepipe.features(x, sample_rate_hz=1e6)
    with pytest.raises(ValueError, match="sample_rate_hz"):
        aepipe.features(x)
    with pytest.raises(ValueError):
        aepipe.cwt(np.ones(16, np.float32), -1.0)
    with pytest.raises(aepipe.ConfigError, match="cut-off"):
        aepipe.trend(pl.DataFrame({"experiment": ["a"], "channel": [1], "hit": [1]}), cutoff="soon")
    with pytest.raises(aepipe.TrendError):
        aepipe.trend(pl.DataFrame({"experiment": ["a"], "channel": [1], "hit": [1]}), columns=["pr_nothing"])
    som = aepipe.Som(3, 3).fit(np.random.default_rng(0).normal(size=(50, 4)))
    with pytest.raises(aepipe.SomError, match="4 values"):
        som.predict(np.zeros((2, 5)))
    with pytest.raises(aepipe.SomError):
        aepipe.Som.load(tmp_path)
    with pytest.raises(aepipe.SomError, match="1 row"):
        aepipe.Som(0, 3).fit(np.zeros((5, 2)))
    # A run that finds no recording is an input error naming what is missing, as on the
    # command line (exit 1), never empty tables.
    with pytest.raises(aepipe.IngestError, match="(?s)no recording aepipe reads.*no such file or folder"):
        aepipe.run(ROOT / "pipelines" / "notched-paper.toml", tmp_path / "nothing-here", tmp_path / "o")
    with pytest.raises(ValueError, match="2 samples"):
        aepipe.pickers.aic(np.ones(1, np.float32))
    for cls in (aepipe.ConfigError, aepipe.IngestError, aepipe.SomError, aepipe.TrendError, aepipe.SimError, aepipe.WorkflowError):
        assert issubclass(cls, aepipe.AepipeError)
