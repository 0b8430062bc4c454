"""Split a features table into two by hit parity (even hits, odd hits), so a model is
trained on one half and judged on the other.

usage: python3 split_features.py FEATURES.parquet EVEN.parquet ODD.parquet
"""
import sys

import polars as pl

df = pl.read_parquet(sys.argv[1])
df.filter(pl.col("hit") % 2 == 0).write_parquet(sys.argv[2])
df.filter(pl.col("hit") % 2 == 1).write_parquet(sys.argv[3])
