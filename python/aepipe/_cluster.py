"""Clustering hits by their own features (``aepipe cluster``): k-means++, Gaussian mixtures
or a SOM's codebook clustered, k chosen by a validity index."""

from __future__ import annotations

from typing import Sequence, Union

import numpy as np
import polars as pl

from . import _aepipe
from ._common import Paths, is_paths, paths_arg

#: The default columns, as ``aepipe cluster``'s (the power ratios ``pr_*`` of the frame
#: are added).
DEFAULT_COLUMNS: tuple[str, ...] = tuple(_aepipe.CLUSTER_DEFAULT_COLUMNS)

VALIDITY_COLUMNS = (
    "method",
    "k",
    "davies_bouldin",
    "silhouette",
    "silhouette_rows",
    "calinski_harabasz",
    "bic",
    "log_likelihood",
    "inertia",
    "rows",
    "chosen",
)


def _columns(frame: pl.DataFrame, columns: Sequence[str] | None) -> list[str]:
    if columns:
        return list(columns)
    cols = [c for c in DEFAULT_COLUMNS if c in frame.columns]
    cols += [c for c in frame.columns if c.startswith("pr_")]
    if not cols:
        raise ValueError("none of the default cluster columns is in the frame; pass columns=")
    return cols


def cluster(
    data: Union[pl.DataFrame, Paths],
    method: str = "kmeans",
    k: Union[int, tuple[int, int], None] = None,
    columns: Sequence[str] | None = None,
    seed: int = 2008,
    n_init: int = 10,
    choose: str = "davies-bouldin",
    max_fit_rows: int = 50_000,
    silhouette_rows: int = 5_000,
    validity: bool = False,
) -> Union[pl.DataFrame, tuple[pl.DataFrame, pl.DataFrame]]:
    """Cluster the rows of a features frame (or of ``features.parquet`` files) as ``aepipe
    cluster`` does: the columns z-scored, ``method`` ``"kmeans"``, ``"gmm"`` or
    ``"som-kmeans"`` fitted for every k of ``k`` (an int, or ``(k_min, k_max)``; default
    2..8) and k chosen by ``choose``. Returns the frame with ``cluster`` (numbered by rising
    mean peak frequency), ``cluster_distance`` and ``cluster_probability`` (mixtures); rows
    with a null or non-finite feature get nulls. With ``validity=True`` also the
    ``validity.parquet`` rows of every k.
    """
    frame = pl.concat([pl.read_parquet(p) for p in paths_arg(data)], how="vertical_relaxed") if is_paths(data) else data
    if not isinstance(frame, pl.DataFrame):
        raise TypeError("data must be a polars DataFrame or features.parquet path(s)")
    cols = _columns(frame, columns)
    x = frame.select([pl.col(c).cast(pl.Float64) for c in cols]).to_numpy()
    ok = np.isfinite(x).all(axis=1)
    key_col = cols.index("peak_freq_hz") if "peak_freq_hz" in cols else 0
    if k is None:
        k_min, k_max = 2, 8
    elif isinstance(k, int):
        k_min = k_max = k
    else:
        k_min, k_max = k
    (c, d, p), rows = _aepipe.cluster_fit(
        np.ascontiguousarray(x[ok]),
        x[ok, key_col].tolist(),
        method,
        k_min,
        k_max,
        seed,
        n_init,
        choose,
        max_fit_rows,
        silhouette_rows,
    )
    n = frame.height
    cl = np.full(n, -1, dtype=np.int64)
    dist = np.full(n, np.nan)
    prob = np.full(n, np.nan)
    cl[ok], dist[ok], prob[ok] = c, d, p
    out = frame.with_columns(
        pl.Series("cluster", cl).cast(pl.Int32).replace(-1, None),
        pl.Series("cluster_distance", dist).fill_nan(None),
        pl.Series("cluster_probability", prob).fill_nan(None),
    )
    if not validity:
        return out
    v = pl.DataFrame([dict(zip(VALIDITY_COLUMNS, r)) for r in rows])
    return out, v


def validity_indices(x: np.ndarray, labels: Sequence[int] | np.ndarray) -> dict[str, float | None]:
    """The Davies–Bouldin, silhouette (exact) and Calinski–Harabasz indices and the inertia
    of a partition of the rows of ``x`` (used as given, not standardised)."""
    db, sil, ch, inertia = _aepipe.cluster_validity(np.ascontiguousarray(x, dtype=np.float64), [int(v) for v in labels])
    return {"davies_bouldin": db, "silhouette": sil, "calinski_harabasz": ch, "inertia": inertia}
