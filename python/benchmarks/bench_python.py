"""Python API benchmarks, printed (never asserted): medians of repeated runs in one process.

    python python/benchmarks/bench_python.py [../shared/data/real]

* read_hits against vallenae's PriDatabase.read_hits on every real Vallen .pridb (same
  file, same run, alternating A B A B), and on a large synthetic one: the demo's
  experiment repeated.
* features of 651 signals of 4 096 samples from a NumPy array on one thread, including
  the conversion to a Polars frame (hits/s).
"""

from __future__ import annotations

import statistics
import sys
import time
import warnings
from pathlib import Path

import numpy as np

import aepipe


def median_time(f, repeats: int) -> float:
    out = []
    for _ in range(repeats):
        t0 = time.perf_counter()
        f()
        out.append(time.perf_counter() - t0)
    return statistics.median(out)


def bench_read_hits(real: Path) -> None:
    import vallenae as vae

    print("read_hits vs vallenae.io.PriDatabase.read_hits (median of 7, A B alternating):")
    for f in sorted(real.glob("**/*.pridb")):
        def ours() -> None:
            with warnings.catch_warnings():
                warnings.simplefilter("ignore")
                aepipe.read_hits(f)

        def theirs() -> None:
            with vae.io.PriDatabase(str(f)) as db:
                db.read_hits()

        ours(), theirs()  # warm the file cache and imports
        a, b = [], []
        for _ in range(7):
            a.append(median_time(ours, 1))
            b.append(median_time(theirs, 1))
        ta, tb = statistics.median(a), statistics.median(b)
        print(f"  {f.name:28s} aepipe {ta * 1e3:8.2f} ms   vallenae {tb * 1e3:8.2f} ms   ratio {ta / tb:5.2f}")


def bench_features() -> None:
    fs = 10e6
    rng = np.random.default_rng(1)
    t = (np.arange(4096) - 500) / fs
    x = rng.normal(0, 2e-5, (651, 4096))
    x += (t >= 0) * 1e-2 * np.exp(-t / 30e-6) * (np.sin(2 * np.pi * 250e3 * t) + 0.6 * np.sin(2 * np.pi * 750e3 * t))
    x = x.astype(np.float32)
    aepipe.features(x[:8], sample_rate_hz=fs, pretrigger_samples=500, threads=1)
    s = median_time(lambda: aepipe.features(x, sample_rate_hz=fs, pretrigger_samples=500, threads=1), 3)
    print(f"features: 651 signals × 4 096 samples, one thread, to a Polars frame: {s:.3f} s = {651 / s:.0f} hits/s (median of 3)")


if __name__ == "__main__":
    real = Path(sys.argv[1]) if len(sys.argv) > 1 else Path(__file__).resolve().parents[2].parent / "shared" / "data" / "real"
    bench_read_hits(real)
    bench_features()
