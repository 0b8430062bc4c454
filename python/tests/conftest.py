"""Shared helpers of the Python package's tests: where the real files and the command line
are, fixtures written here by the tests' own code, and the skip-or-fail rule.

Real files are read from ../shared/data/real beside the repository. A test that cannot run
skips locally and fails with AEPIPE_REQUIRE_ALL=1 (set by .ci/run).
"""

from __future__ import annotations

import os
import subprocess
import tempfile
from pathlib import Path

import numpy as np
import pytest

ROOT = Path(__file__).resolve().parents[2]
REAL = ROOT.parent / "shared" / "data" / "real"
REQUIRE_ALL = os.environ.get("AEPIPE_REQUIRE_ALL") == "1"


def pytest_configure(config: pytest.Config) -> None:
    """The long-call tests carry a hang guard (`@pytest.mark.timeout`, pytest-timeout's thread
    method prints every thread's stack where a test hung). Without the plugin the guard is
    gone: a skip-worthy absence locally, a failure with AEPIPE_REQUIRE_ALL=1."""
    config.addinivalue_line("markers", "timeout(seconds): pytest-timeout's hang guard")
    if REQUIRE_ALL and not config.pluginmanager.hasplugin("timeout"):
        raise pytest.UsageError("AEPIPE_REQUIRE_ALL=1 needs pytest-timeout (the hang guard)")
    # The reference maps' cache of every aepipe the tests start (in process and as the
    # command) is the session's own, never the user's ~/.cache.
    os.environ["XDG_CACHE_HOME"] = tempfile.mkdtemp(prefix="aepipe-pytest-cache-")


def need(ok: bool, why: str) -> None:
    """Skip (locally) or fail (AEPIPE_REQUIRE_ALL=1) when a test cannot run."""
    if not ok:
        if REQUIRE_ALL:
            pytest.fail(f"cannot run and AEPIPE_REQUIRE_ALL=1: {why}")
        pytest.skip(why)


def need_module(name: str):
    """Import a test dependency (vallenae, scipy), or skip/fail as `need` says."""
    import importlib

    try:
        return importlib.import_module(name)
    except ImportError:
        need(False, f"python module {name} is not installed")


def real(*parts: str) -> Path:
    p = REAL.joinpath(*parts)
    need(p.exists(), f"no {p} (the real data sets)")
    return p


def cli() -> Path:
    """The command line built by `cargo test` / `cargo build` (debug or release)."""
    for p in (ROOT / "target" / "debug" / "aepipe", ROOT / "target" / "release" / "aepipe"):
        if p.is_file():
            return p
    need(False, "no aepipe binary in target/ (run cargo build first)")
    raise AssertionError


def aepipe_cli(*args: object) -> str:
    """Run the command line; its stdout. A failure shows its stderr."""
    r = subprocess.run([str(cli()), *map(str, args)], capture_output=True, text=True)
    assert r.returncode == 0, f"aepipe {' '.join(map(str, args))}: {r.stderr}"
    return r.stdout


def synthetic_signals(n: int, length: int, fs: float, seed: int) -> np.ndarray:
    """Decaying 250/750 kHz bursts (every third signal a 1.1 MHz pulse) in noise, starting at
    sample 500, amplitudes spread over 40 dB."""
    rng = np.random.default_rng(seed)
    t = (np.arange(length) - 500) / fs
    out = rng.normal(0, 2e-5, (n, length))
    for i in range(n):
        a = 10 ** rng.uniform(-3.5, -1.5)
        on = t >= 0
        if i % 3 == 2:
            w = np.exp(-((t - 2e-6) / 1e-6) ** 2) * np.sin(2 * np.pi * 1.1e6 * t)
        else:
            share = rng.uniform(0.3, 1.0)
            w = on * np.exp(-t / 30e-6) * (share * np.sin(2 * np.pi * 250e3 * t) + (1.3 - share) * np.sin(2 * np.pi * 750e3 * t))
        out[i] += a * w
    return out.astype(np.float32)


def write_float_wav(path: Path, x: np.ndarray, fs: int) -> None:
    """A 32-bit float WAV (format 3), written here so the test owns its fixture format."""
    data = x.astype("<f4").tobytes()
    hdr = b"RIFF" + (36 + len(data)).to_bytes(4, "little") + b"WAVE"
    fmt = (
        b"fmt " + (16).to_bytes(4, "little") + (3).to_bytes(2, "little") + (1).to_bytes(2, "little")
        + fs.to_bytes(4, "little") + (fs * 4).to_bytes(4, "little") + (4).to_bytes(2, "little")
        + (32).to_bytes(2, "little")
    )
    path.write_bytes(hdr + fmt + b"data" + len(data).to_bytes(4, "little") + data)


def wav_folder(folder: Path, x: np.ndarray, fs: int) -> Path:
    folder.mkdir(parents=True, exist_ok=True)
    for i, s in enumerate(x):
        write_float_wav(folder / f"hit{i + 1:04d}.wav", s, fs)
    return folder


@pytest.fixture(scope="session")
def labelled_features(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, Path]:
    """A WAV folder of 150 synthetic bond/fibre signals and the command line's features of
    it (features.parquet), shared by the SOM and trend tests."""
    d = tmp_path_factory.mktemp("labelled")
    fs = 10_000_000
    folder = wav_folder(d / "wav", synthetic_signals(150, 4096, fs, seed=21), fs)
    cfg = d / "p.toml"
    cfg.write_text("[ingest]\npretrigger_samples = 500\n")
    aepipe_cli("features", "--quiet", "--config", cfg, "--out", d / "out", folder)
    return d / "out" / "features.parquet", cfg


def feed_fifo(fifo: Path, data: bytes, stop, fed: list | None = None) -> None:
    """Serve `data` to every reader that opens the named pipe `fifo`, until `stop` is set
    (discovery, the input hashes and the reader each open it once). A test's job that reads
    the pipe can go on only once this runs: what the test releases, not a timing."""
    import time

    while not stop.is_set():
        try:
            fd = os.open(fifo, os.O_WRONLY | os.O_NONBLOCK)
        except OSError:  # no reader yet
            time.sleep(0.005)
            continue
        try:
            os.write(fd, data)
            if fed is not None:
                fed.append(1)
        except OSError:  # the reader let go first
            pass
        finally:
            os.close(fd)
