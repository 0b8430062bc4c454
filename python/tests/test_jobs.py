"""Whole jobs from Python — simulation, reference library, the run — against the command
line, and what a long call does on Ctrl-C."""

from __future__ import annotations

import _thread
import contextlib
import glob
import os
import sys
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


@pytest.mark.timeout(120)
def test_a_long_call_returns_on_ctrl_c_and_cleans_up(tmp_path: Path) -> None:
    """Each job interrupted here is one that cannot finish first, whatever the machine: a
    library of 2 048 simulations (the embedded one is 64), and a feature run that waits on
    an input the test releases only after the interrupt. The interrupt is sent once the call
    is known to be inside its wait: its progress line has been drawn (the call draws it from
    its wait loop, so the job is running), never after a fixed delay, which on a loaded
    machine could land before the call began or in the test's own code. That the call
    raises KeyboardInterrupt after the interrupt was sent, and that its temporary folder is
    gone once its job has stopped, is what is checked; no duration is asserted on a shared
    machine. A call that ignored the request would run for many minutes: pytest-timeout's
    guard ends it at 120 s and prints every thread's stack into the log."""
    leftovers = lambda: glob.glob(os.path.join(tempfile.gettempdir(), f"aepipe-py-{os.getpid()}-*"))  # noqa: E731
    # The embedded library with 32 times its material draws: 2 048 simulations of 6 000
    # steps cannot be done before the first progress line of any build.
    lib = (ROOT / "pipelines" / "reference-library.toml").read_text()
    assert "variants = 4\n" in lib
    big = tmp_path / "big-library.toml"
    big.write_text(lib.replace("variants = 4\n", "variants = 128\n"))
    with _interrupt_once_drawn() as sent:
        with pytest.raises(KeyboardInterrupt):
            aepipe.reference_library(big, threads=2, progress=True)
    assert len(sent) == 1, "the call returned before the interrupt was sent"
    # The job stopped (its next simulation saw the request) and its folder went with it.
    _gone(leftovers, 30)
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
        try:
            with _interrupt_once_drawn(then=feeder.start) as sent:
                with pytest.raises(KeyboardInterrupt):
                    aepipe.features(d, threads=1, progress=True)
            assert len(sent) == 1, "the call returned before the interrupt was sent"
            _gone(leftovers, 30)
        finally:
            stop.set()


class _Drawn:
    """A stand-in for ``sys.stderr`` that notes the first progress line a call draws."""

    def __init__(self) -> None:
        self.drawn = threading.Event()

    def write(self, text: str) -> int:
        if "aepipe: " in text:
            self.drawn.set()
        return len(text)

    def flush(self) -> None:
        pass


@contextlib.contextmanager
def _interrupt_once_drawn(then=None):
    """While the body runs, a thread waits until the call's progress line is drawn, then sends
    one Ctrl-C (and calls ``then``). Yields the list the send is noted in. The thread is
    joined before the context ends; a body that ended before the line was drawn (a failure)
    gets no interrupt at all."""
    sent: list[float] = []
    pen = _Drawn()
    ended = threading.Event()

    def interrupt() -> None:
        pen.drawn.wait(60)
        if ended.is_set():
            return
        sent.append(time.perf_counter())
        _thread.interrupt_main()
        if then is not None:
            then()

    t = threading.Thread(target=interrupt, daemon=True)
    saved, sys.stderr = sys.stderr, pen
    t.start()
    try:
        yield sent
    finally:
        sys.stderr = saved
        ended.set()
        pen.drawn.set()
        t.join()


def _gone(leftovers, seconds: float) -> None:
    deadline = time.time() + seconds
    while leftovers() and time.time() < deadline:
        time.sleep(0.2)
    assert not leftovers(), leftovers()


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
