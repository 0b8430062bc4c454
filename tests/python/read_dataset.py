"""Open a Hive-partitioned aepipe dataset folder (DIR/features/experiment=<id>/part-K.parquet)
with Polars, DuckDB and pyarrow; print each reader's row and experiment counts."""
import sys

import duckdb
import polars as pl
import pyarrow.dataset as ds

d = sys.argv[1]
p = pl.scan_parquet(f"{d}/**/*.parquet", hive_partitioning=True).collect()
print(f"polars {p.height} rows, {p['experiment'].n_unique()} experiments")
rows, exps = duckdb.sql(
    f"select count(*), count(distinct experiment) from read_parquet('{d}/*/*.parquet', hive_partitioning=true)"
).fetchall()[0]
print(f"duckdb {rows} rows, {exps} experiments")
t = ds.dataset(d, partitioning="hive", format="parquet").to_table()
print(f"pyarrow {t.num_rows} rows, {len(set(t.column('experiment').to_pylist()))} experiments")
