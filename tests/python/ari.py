"""Adjusted Rand index of tables' class columns against a features table's column, joined
by hit key (scikit-learn's adjusted_rand_score).

usage: python3 ari.py FEATURES.parquet TRUTH_COLUMN NAME=TABLE.parquet:COLUMN ...
prints a JSON object {NAME: ari, ...}
"""
import json
import sys

import polars as pl
from sklearn.metrics import adjusted_rand_score

keys = ["experiment", "channel", "hit"]
truth = pl.read_parquet(sys.argv[1]).select(*keys, pl.col(sys.argv[2]).alias("truth"))
out = {}
for spec in sys.argv[3:]:
    name, rest = spec.split("=", 1)
    path, column = rest.rsplit(":", 1)
    t = pl.read_parquet(path).select(*keys, pl.col(column).cast(pl.String).alias("label"))
    j = truth.join(t, on=keys)
    assert j.height == truth.height, (name, j.height, truth.height)
    out[name] = adjusted_rand_score(j["truth"], j["label"])
print(json.dumps(out))
