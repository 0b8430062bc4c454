"""Python API benchmarks, printed (never asserted): medians of repeated runs in one process.

    python python/benchmarks/bench_python.py [REAL_DATA_DIR] [--cli target/release/aepipe]

* read_hits against vallenae's PriDatabase.read_hits on every real Vallen .pridb (same
  file, same run, alternating A B A B) and, with --cli, on a large synthetic one (a
  20 000-source test of the demo's strip: 40 000 hits, written by `aepipe synth-experiment`).
* features of 651 signals of 4 096 samples from a NumPy array on one thread, including
  the conversion to a Polars frame (hits/s, and the CPU time to show it was one thread).

Use a release build of the package (`pip install .` or `maturin develop --release`): the
dev profile `maturin develop` builds by default is several times slower.
"""

from __future__ import annotations

import os
import statistics
import subprocess
import sys
import tempfile
import time
import warnings
from pathlib import Path

os.environ.setdefault("TQDM_DISABLE", "1")  # vallenae's progress bars, not the work

import numpy as np

import aepipe


def timed(f, repeats: int) -> float:
    out = []
    for _ in range(repeats):
        t0 = time.perf_counter()
        f()
        out.append(time.perf_counter() - t0)
    return statistics.median(out)


def bench_read_hits_file(f: Path, repeats: int) -> None:
    import vallenae as vae

    def ours() -> None:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            aepipe.read_hits(f)

    def theirs() -> None:
        with vae.io.PriDatabase(str(f)) as db:
            db.read_hits()

    ours(), theirs()  # warm the file cache and imports
    a, b = [], []
    for _ in range(repeats):
        a.append(timed(ours, 1))
        b.append(timed(theirs, 1))
    ta, tb = statistics.median(a), statistics.median(b)
    n = aepipe.read_hits(f).height
    print(f"  {f.name:32s} {n:6d} hits  aepipe {ta * 1e3:8.2f} ms   vallenae {tb * 1e3:8.2f} ms   ratio {ta / tb:5.2f}")


def bench_read_hits(real: Path, cli: str | None) -> None:
    print("read_hits vs vallenae.io.PriDatabase.read_hits (median of 7, A B alternating; ratio < 1: aepipe faster):")
    for f in sorted(real.glob("**/*.pridb")):
        bench_read_hits_file(f, 7)
    if cli:
        with tempfile.TemporaryDirectory() as d:
            subprocess.run([cli, "synth-experiment", "--out", d, "--hits", "20000", "--seed", "5"], check=True, capture_output=True)
            for f in sorted(Path(d).rglob("*.pridb")):
                bench_read_hits_file(f, 5)


def bench_features() -> None:
    fs = 10e6
    rng = np.random.default_rng(1)
    t = (np.arange(4096) - 500) / fs
    x = rng.normal(0, 2e-5, (651, 4096))
    amp = 10 ** rng.uniform(-3.5, -1.5, (651, 1))
    x += amp * (t >= 0) * np.exp(-t / 30e-6) * (np.sin(2 * np.pi * 250e3 * t) + 0.6 * np.sin(2 * np.pi * 750e3 * t))
    x = x.astype(np.float32)
    aepipe.features(x[:8], sample_rate_hz=fs, pretrigger_samples=500, threads=1)
    wall, cpu = [], []
    for _ in range(5):
        c0, t0 = time.process_time(), time.perf_counter()
        f = aepipe.features(x, sample_rate_hz=fs, pretrigger_samples=500, threads=1)
        wall.append(time.perf_counter() - t0)
        cpu.append(time.process_time() - c0)
    s, c = statistics.median(wall), statistics.median(cpu)
    assert f.height == 651
    print(
        f"features: 651 signals × 4 096 samples from a NumPy array, threads=1, to a Polars frame: "
        f"{s:.3f} s = {651 / s:.0f} hits/s (median of 5; CPU {c:.3f} s, min {651 / max(wall):.0f} – max {651 / min(wall):.0f} hits/s)"
    )


if __name__ == "__main__":
    args = sys.argv[1:]
    cli = None
    if "--cli" in args:
        k = args.index("--cli")
        cli = args[k + 1]
        del args[k : k + 2]
    real = Path(args[0]) if args else Path(__file__).resolve().parents[2].parent / "shared" / "data" / "real"
    bench_read_hits(real, cli)
    bench_features()
