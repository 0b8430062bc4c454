"""The scikit-learn side of `aepipe bench cluster`: read the matrix, z-score it, fit
KMeans(n_init=10) or GaussianMixture (full covariances, its k-means start), write the
labels (as aepipe writes its clusters).

usage: python3 bench_cluster.py MATRIX.parquet kmeans|gmm K
"""
import sys

import numpy as np
import polars as pl
from sklearn.cluster import KMeans
from sklearn.mixture import GaussianMixture
from sklearn.preprocessing import StandardScaler

path, method, k = sys.argv[1], sys.argv[2], int(sys.argv[3])
df = pl.read_parquet(path)
x = StandardScaler().fit_transform(df.select([c for c in df.columns if c.startswith("f")]).to_numpy())
if method == "kmeans":
    labels = KMeans(k, n_init=10, random_state=0).fit_predict(x)
else:
    labels = GaussianMixture(k, covariance_type="full", random_state=0).fit_predict(x)
df.select("experiment", "channel", "hit").with_columns(pl.Series("cluster", labels.astype(np.int32))).write_parquet(path + f".{method}.sk.parquet")
