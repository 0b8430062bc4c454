"""scikit-learn's KMeans on the matrix aepipe clustered, for comparing the two (tests/it/
vendor.rs): the same rows (one per source, every cluster column usable), the same columns z-scored with the
population mean and standard deviation (a constant column divided by 1), the same k and
n_init; five seeds. Prints JSON: aepipe's inertia (its validity table) and adjusted Rand
index against the truth column, and scikit-learn's per seed.

usage: python3 kmeans_reference.py FEATURES.parquet CLUSTER_DIR TRUTH_COLUMN
"""
import json
import sys

try:
    import numpy as np
    import polars as pl
    from sklearn.cluster import KMeans
    from sklearn.metrics import adjusted_rand_score
except ImportError as e:
    print(f"missing: {e}", file=sys.stderr)
    sys.exit(3)

feats, cdir, truth = sys.argv[1], sys.argv[2], sys.argv[3]
model = json.load(open(f"{cdir}/model.json"))
cols = model["columns"]
k = int(model["k"])
n_init = int(model["settings"]["n_init"])
keys = ["experiment", "channel", "hit"]
f = pl.read_parquet(feats)
# Sources, not hits: where events were built, the hit that opened each (aepipe's SourceRows).
if "event_first" in f.columns:
    f = f.filter(pl.col("event_first").is_null() | pl.col("event_first"))
f = f.select(*keys, pl.col(truth).cast(pl.String).alias("_truth"), *cols)
x = f.select(cols).to_numpy().astype(float)
usable = np.isfinite(x).all(axis=1)
x, f = x[usable], f.filter(pl.Series(usable))
sd = x.std(axis=0)
z = (x - x.mean(axis=0)) / np.where(sd > 0, sd, 1.0)
ours = pl.read_parquet(f"{cdir}/clusters.parquet").select(*keys, "cluster")
j = f.join(ours, on=keys, how="left")
assert j["cluster"].null_count() == 0 and j.height == len(z), "aepipe clustered other rows"
validity = pl.read_parquet(f"{cdir}/validity.parquet").filter(pl.col("k") == k)
sk = [KMeans(k, n_init=n_init, random_state=s).fit(z) for s in range(5)]
print(json.dumps({
    "k": k, "n_init": n_init, "rows": len(z), "columns": len(cols),
    "ours_inertia": float(validity["inertia"][0]),
    "ours_ari": adjusted_rand_score(j["_truth"], j["cluster"]),
    "sk_inertia": [float(m.inertia_) for m in sk],
    "sk_ari": [adjusted_rand_score(j["_truth"], m.labels_) for m in sk],
}))
