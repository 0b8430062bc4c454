"""Whole-batch analysis: trend statistics (ch. 4.5.5) and the self-organising map (ch. 5)."""

from __future__ import annotations

import os
import tempfile
from typing import Sequence, Union

import numpy as np
import polars as pl

from . import _aepipe
from ._common import Paths, PathLike, is_paths, paths_arg

Features = Union[pl.DataFrame, Paths]


def trend(
    features_df: Features,
    *,
    cutoff: str = "peak-load",
    columns: Sequence[str] | None = None,
    alpha: float = 0.01,
    exclude_outside: bool = False,
    min_load_span_n: float = 1.0,
    min_hits: int = 10,
) -> pl.DataFrame:
    """The trend statistics of each experiment and channel (``trend.parquet``'s rows):
    Pearson's r of each power ratio (or ``columns``) against the AE number, its p value,
    the least-squares line and whether p < ``alpha`` (Tables 4.2/4.3).

    ``features_df`` is a features frame (as :func:`features` returns, or read from
    ``features.parquet``) or paths to feature tables. ``cutoff`` is ``"peak-load"`` (hits up
    to the one at the highest load), ``"none"``, ``"time:SECONDS"`` or ``"hits:N"``. Where
    events were built, each event counts once (channel 0); ``exclude_outside`` also leaves
    out events outside the configured zone. A load channel spanning less than
    ``min_load_span_n`` newtons, or within its own noise, is no load: no peak-load cut (the
    ``cutoff`` column says why). A series of fewer than ``min_hits`` hits states no trend:
    r and p are null and ``note`` says ``n = 3: too few hits for a trend``.

    >>> t = aepipe.trend(aepipe.features("test.pridb"), cutoff="none")   # doctest: +SKIP
    >>> t.filter(pl.col("significant")).select("column", "r", "p")        # doctest: +SKIP
    """
    cols = None if columns is None else [str(c) for c in columns]
    if isinstance(features_df, pl.DataFrame):
        with tempfile.TemporaryDirectory(prefix="aepipe-trend-") as d:
            p = os.path.join(d, "features.parquet")
            features_df.write_parquet(p)
            stream = _aepipe.trend(
                [p], cutoff, cols, float(alpha), exclude_outside, float(min_load_span_n), int(min_hits)
            )
            return pl.DataFrame(stream)
    if not is_paths(features_df):
        raise TypeError("features_df must be a polars.DataFrame or paths to feature tables")
    stream = _aepipe.trend(
        paths_arg(features_df), cutoff, cols, float(alpha), exclude_outside, float(min_load_span_n), int(min_hits)
    )
    return pl.DataFrame(stream)


def _matrix(x: np.ndarray | pl.DataFrame, columns: Sequence[str]) -> tuple[np.ndarray, np.ndarray]:
    """The rows as a float64 matrix, and which rows are usable (no null, all finite)."""
    if isinstance(x, pl.DataFrame):
        if not columns:
            raise ValueError("a frame needs the map's columns (Som(columns=...))")
        blocks = []
        for c in columns:
            s = x.get_column(c)
            if isinstance(s.dtype, pl.Array) and s.null_count() == 0:
                blocks.append(np.asarray(s.to_numpy(), dtype=np.float64).reshape(len(s), -1))
            elif isinstance(s.dtype, (pl.Array, pl.List)):
                vals = s.to_list()
                width = next((len(v) for v in vals if v is not None), 0)
                blocks.append(
                    np.array(
                        [v if v is not None and len(v) == width else [np.nan] * width for v in vals],
                        dtype=np.float64,
                    ).reshape(len(vals), width)
                )
            else:
                blocks.append(s.cast(pl.Float64).fill_null(np.nan).to_numpy().reshape(-1, 1))
        m = np.hstack(blocks) if blocks else np.empty((x.height, 0))
    else:
        m = np.asarray(x, dtype=np.float64)
        if m.ndim == 1:
            m = m[np.newaxis, :]
        if m.ndim != 2:
            raise ValueError(f"expected a 2-D array (rows are inputs), got {m.ndim}-D")
    ok = np.isfinite(m).all(axis=1)
    return np.ascontiguousarray(m), ok


class Som:
    """A self-organising map (Kohonen, ch. 5.3): a ``rows × cols`` grid of nodes trained
    online with the thesis's Table 5.2 stages (ordering α 0.05, σ 10, 1 000 iterations;
    convergence α 0.01, σ 3, 10 000 iterations), Gaussian neighbourhood, seeded so that the
    same data give the same map bit for bit.

    Inputs are rows of a matrix, or a features frame whose ``columns`` are used (default
    ``["tf_bins"]``, the 200 time/frequency bins the thesis trains on). Models are saved in
    and loaded from the folder ``aepipe som train`` writes, so a map moves between Python
    and the command line (``aepipe som classify DIR features.parquet``).

    >>> som = aepipe.Som(10, 10, seed=2008).fit(f, labels="criteria_label")   # doctest: +SKIP
    >>> som.predict(f)[:5]                                                     # doctest: +SKIP
    >>> som.save("model"); same = aepipe.Som.load("model")                     # doctest: +SKIP
    """

    def __init__(
        self,
        rows: int = 10,
        cols: int = 10,
        *,
        seed: int = 2008,
        columns: Sequence[str] | None = None,
        standardise: bool = False,
    ) -> None:
        self.rows = int(rows)
        self.cols = int(cols)
        self.seed = int(seed)
        self.columns = None if columns is None else [str(c) for c in columns]
        self.standardise = bool(standardise)
        self._model: _aepipe.SomModel | None = None

    def __repr__(self) -> str:
        state = "unfitted" if self._model is None else (
            f"dim {self._model.dim}, " + ("labelled" if self._model.labels else "unlabelled")
        )
        return f"Som({self.rows}×{self.cols}, seed={self.seed}, {state})"

    def _cols_for(self, x: object) -> list[str]:
        if self.columns is not None:
            return self.columns
        return ["tf_bins"] if isinstance(x, pl.DataFrame) else []

    def _fitted(self) -> _aepipe.SomModel:
        if self._model is None:
            raise ValueError("the map is not fitted: call fit() or Som.load() first")
        return self._model

    def fit(
        self,
        X: np.ndarray | pl.DataFrame,
        labels: Sequence[str | None] | np.ndarray | str | None = None,
    ) -> "Som":
        """Train on every row of ``X`` (rows with a null or non-finite value are left out)
        and, with ``labels``, label each node by the majority of the rows it wins (nodes
        no row reaches take their nearest labelled node's label). ``labels`` is one label
        per row (``None`` rows train but do not vote), or a column name of a frame.
        Returns the map itself.
        """
        cols = self._cols_for(X)
        label_column = "label"
        if isinstance(labels, str):
            if not isinstance(X, pl.DataFrame):
                raise TypeError("labels as a column name needs a frame")
            label_column = labels
            labels = X.get_column(labels).cast(pl.String).to_list()
        m, ok = _matrix(X, cols)
        lab = None
        if labels is not None:
            lab = [None if v is None else str(v) for v in list(labels)]
            if len(lab) != m.shape[0]:
                raise ValueError(f"{len(lab)} labels for {m.shape[0]} rows")
            lab = [v for v, k in zip(lab, ok) if k]
        m = m[ok]
        if not cols and m.shape[1] == 200:
            cols = ["tf_bins"]
        self.columns = cols or None
        self._model = _aepipe.som_fit(
            np.ascontiguousarray(m), lab, self.rows, self.cols, self.seed, cols, label_column, self.standardise
        )
        return self

    def winners(self, X: np.ndarray | pl.DataFrame) -> np.ndarray:
        """The best-matching node of each row, ``r·cols + c`` (-1 for a row with a null or
        non-finite value)."""
        model = self._fitted()
        m, ok = _matrix(X, self._cols_for(X))
        out = np.full(m.shape[0], -1, dtype=np.int64)
        if ok.any():
            out[ok] = model.bmu(m[ok])[0]
        return out

    def predict(self, X: np.ndarray | pl.DataFrame) -> np.ndarray:
        """Each row's class: its best-matching node's label (the map's reading alone; the
        command line's SOM stage also reads the erroneous area with ``quality_fault``). A
        map fitted without labels returns the node index instead. Rows with a null or
        non-finite value get ``None`` (-1 for node indices).
        """
        model = self._fitted()
        nodes = self.winners(X)
        if not model.labels:
            return nodes
        labels = np.array(model.labels, dtype=object)
        out = np.empty(nodes.shape[0], dtype=object)
        ok = nodes >= 0
        out[ok] = labels[nodes[ok]]
        out[~ok] = None
        return out

    def quantization_error(self, X: np.ndarray | pl.DataFrame) -> float:
        """Mean distance of the (usable) rows to their best-matching nodes."""
        m, ok = _matrix(X, self._cols_for(X))
        return float(self._fitted().quantization_error(m[ok]))

    def novelty_threshold(self, quantile: float = 0.99) -> float | None:
        """The distance beyond which a row is unlike the map's references.

        The conformal ``quantile`` of the distances of training rows held out of the
        map by 5-fold cross-validation (as ``[som] novelty_quantile``); None for a map
        without calibration (fewer than 10 rows). Compare with the distances of
        ``distances`` to flag novel rows (``novel`` does).
        """
        return self._fitted().novelty_threshold(quantile)

    def distances(self, X: np.ndarray | pl.DataFrame) -> np.ndarray:
        """Each row's quantisation error: its distance to its best-matching node (NaN for
        a row with a null or non-finite value)."""
        model = self._fitted()
        m, ok = _matrix(X, self._cols_for(X))
        out = np.full(m.shape[0], np.nan)
        if ok.any():
            out[ok] = model.bmu(m[ok])[1]
        return out

    def novel(self, X: np.ndarray | pl.DataFrame, quantile: float = 0.99) -> np.ndarray | None:
        """True for rows beyond ``novelty_threshold(quantile)`` (False for unusable rows,
        whose ``distances`` are NaN); None for a map without calibration."""
        t = self.novelty_threshold(quantile)
        if t is None:
            return None
        return self.distances(X) > t

    def topographic_error(self, X: np.ndarray | pl.DataFrame) -> float:
        """Share of the (usable) rows whose two best nodes are not grid neighbours."""
        m, ok = _matrix(X, self._cols_for(X))
        return float(self._fitted().topographic_error(m[ok]))

    def umatrix(self) -> np.ndarray:
        """The U-matrix: each node's mean distance to its grid neighbours (rows × cols)."""
        return self._fitted().umatrix()

    @property
    def codebook(self) -> np.ndarray:
        """The node weights, rows × cols × dim (in the map's scaled space)."""
        return self._fitted().codebook()

    @property
    def labels(self) -> np.ndarray | None:
        """The node labels as a rows × cols array, or None for an unlabelled map."""
        model = self._fitted()
        if not model.labels:
            return None
        return np.array(model.labels, dtype=object).reshape(model.rows, model.cols)

    def save(self, path: PathLike) -> None:
        """Write the model folder (``model.json``, ``model.cod``) that ``aepipe som
        classify`` and :meth:`Som.load` read."""
        model = self._fitted()
        if not model.columns:
            raise ValueError(
                "the map does not know its feature columns: give Som(columns=[...]) so that "
                "the command line can apply it to features.parquet"
            )
        model.save(os.fspath(path))

    @classmethod
    def load(cls, path: PathLike) -> "Som":
        """Read a model folder written by ``aepipe som train``, ``aepipe run`` (its
        ``som/model``) or :meth:`save`; also its ``model.json`` or a SOM_PAK ``.cod`` beside
        one."""
        model = _aepipe.SomModel.load(os.fspath(path))
        som = cls(model.rows, model.cols, seed=model.seed, columns=model.columns or None,
                  standardise=model.standardised)
        som._model = model
        return som
