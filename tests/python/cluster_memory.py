"""Peak memory of `aepipe cluster` at growing row counts (issue 39: whole-batch streaming,
<= 500 MB at 10^7 rows). Each matrix (4 blobs in 20 columns, polars-written, row groups of
65 536) is made by a child process, so this process stays small (a child forked from a
large process reports the parent's pages in its peak RSS); aepipe's own peak comes from
os.wait4 on its process.

usage: python3 cluster_memory.py AEPIPE DIR N [N ...]
"""
import os
import subprocess
import sys
import time

MAKE = """
import sys, numpy as np, polars as pl
n, path = int(sys.argv[1]), sys.argv[2]
rng = np.random.default_rng(1)
x = rng.normal(0, 3, (4, 20))[np.arange(n) % 4] + rng.standard_normal((n, 20))
pl.DataFrame({f"f{j}": x[:, j] for j in range(20)}).with_columns(
    pl.lit("big").alias("experiment"), pl.lit(1, dtype=pl.Int32).alias("channel"),
    pl.int_range(1, n + 1, dtype=pl.Int64).alias("hit")).write_parquet(path, row_group_size=65536)
"""

aepipe, d = sys.argv[1], sys.argv[2]
cols = ",".join(f"f{j}" for j in range(20))
for n in map(int, sys.argv[3:]):
    path = f"{d}/m{n}.parquet"
    subprocess.run([sys.executable, "-c", MAKE, str(n), path], check=True)
    t = time.time()
    p = subprocess.Popen([aepipe, "cluster", path, "--out", f"{d}/out{n}", "--columns", cols, "--k", "2..6"],
                         stdout=subprocess.DEVNULL)
    _, status, usage = os.wait4(p.pid, 0)
    assert os.waitstatus_to_exitcode(status) == 0
    print(f"{n} rows: {time.time() - t:.1f} s, peak RSS {usage.ru_maxrss / 1024:.0f} MB")
