"""The same SOM recipe in MiniSom (the independent peer), judged on held-out hits: train a
10x10 map on the training set aepipe drew (MODEL/train.dat: the same vectors), with Table
5.2's two stages (lr 0.05, sigma 10, 1000 steps; lr 0.01, sigma 3, 10000 steps; gaussian,
linear decay), label each node by the majority of the training vectors it wins, then, as
aepipe does, relabel every node that a labelled row of the training table wins by those
rows' majority; classify every row of the TEST table. Prints JSON: the held-out accuracy of
MiniSom and of aepipe's classification.parquet of the same TEST table.

usage: python3 som_minisom.py TRAIN.parquet MODEL_DIR TEST.parquet CLASSIFICATION.parquet LABEL
"""
import collections
import json
import sys

import numpy as np
import polars as pl
from minisom import MiniSom

train_table, model, features, classification, label = sys.argv[1:6]
lines = open(f"{model}/train.dat").read().split("\n")
dim = int(lines[0].split()[0])
train_x, train_y = [], []
for ln in lines[1:]:
    parts = ln.split()
    if len(parts) < dim + 1:
        continue
    train_x.append([float(v) for v in parts[:dim]])
    train_y.append(" ".join(parts[dim:]))
train_x = np.array(train_x)

df = pl.read_parquet(features)
x = np.array(df["tf_bins"].to_list(), dtype=np.float64)
y = df[label].cast(pl.Utf8).to_list()
cal = pl.read_parquet(train_table)
cal_x = np.array(cal["tf_bins"].to_list(), dtype=np.float64)
cal_y = cal[label].cast(pl.Utf8).to_list()

som = MiniSom(10, 10, dim, sigma=10.0, learning_rate=0.05, decay_function="linear_decay_to_zero",
              sigma_decay_function="linear_decay_to_one", neighborhood_function="gaussian",
              topology="rectangular", activation_distance="euclidean", random_seed=2008)
som.random_weights_init(train_x)
som.train_random(train_x, 1000)
som._learning_rate, som._sigma = 0.01, 3.0
som.train_random(train_x, 10000)
votes = collections.defaultdict(collections.Counter)
for v, l in zip(train_x, train_y):
    votes[som.winner(v)][l] += 1
node_label = {n: c.most_common(1)[0][0] for n, c in votes.items()}
cal_votes = collections.defaultdict(collections.Counter)
for v, l in zip(cal_x, cal_y):
    cal_votes[som.winner(v)][l] += 1
node_label.update({n: c.most_common(1)[0][0] for n, c in cal_votes.items()})
# A node no training vector wins takes the label of the nearest labelled node.
labelled = list(node_label)
def classify(v):
    w = som.winner(v)
    if w in node_label:
        return node_label[w]
    n = min(labelled, key=lambda m: (m[0] - w[0]) ** 2 + (m[1] - w[1]) ** 2)
    return node_label[n]
pred = [classify(v) for v in x]
ok = np.array([p == t for p, t in zip(pred, y)])

c = pl.read_parquet(classification)
keys = df.select(["experiment", "channel", "hit"]).with_row_index("i")
c = c.join(keys, on=["experiment", "channel", "hit"], how="inner").sort("i")
mine = np.array([a == b for a, b in zip(c["som_label"].to_list(), c["reference_label"].to_list())])
assert len(mine) == len(y)
print(json.dumps({
    "train_rows": int(cal.height), "test_rows": int(len(y)), "training_set": len(train_y),
    "minisom": float(ok.mean()), "aepipe": float(mine.mean()),
}))
