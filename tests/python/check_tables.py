"""Read every Parquet table in the given folders with pyarrow, pandas and Polars.

Run by the integration test `python_readers_open_every_table` (skipped when these modules are
not installed; `.ci/run` installs them). Prints one line per table and exits non-zero if a
reader fails or the readers disagree on the shape.
"""
import pathlib
import sys

import pandas as pd
import polars as pl
import pyarrow.parquet as pq

failed = False
for folder in sys.argv[1:]:
    for path in sorted(pathlib.Path(folder).rglob("*.parquet")):
        t = pq.read_table(path)
        df = pd.read_parquet(path)
        pf = pl.read_parquet(path)
        shapes = {(t.num_rows, t.num_columns), df.shape, pf.shape}
        meta = pq.read_metadata(path).metadata or {}
        ok = len(shapes) == 1 and b"aepipe.table" in meta
        failed |= not ok
        print(f"{'ok ' if ok else 'BAD'} {path.name}: {t.num_rows} rows x {t.num_columns} cols, "
              f"table={meta.get(b'aepipe.table', b'?').decode()}")
sys.exit(1 if failed else 0)
