"""The SOM and the trend from Python, against the command line and SciPy."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import polars as pl
import pytest

import aepipe
from conftest import aepipe_cli, need_module

KEY = ["experiment", "channel", "hit"]


def test_a_map_the_command_line_trained_classifies_the_same_in_python(tmp_path: Path, labelled_features) -> None:
    feats, _ = labelled_features
    model = tmp_path / "model"
    aepipe_cli("som", "train", feats, "--label", "criteria_label", "--fraction", "0.5", "--out", model)
    aepipe_cli("som", "classify", model, feats, "--out", tmp_path / "cls")
    cls = pl.read_parquet(tmp_path / "cls" / "classification.parquet")
    f = pl.read_parquet(feats).join(cls.select(KEY + ["bmu_row", "bmu_col", "bmu_distance", "node_label"]), on=KEY)
    assert f.height == cls.height > 100
    som = aepipe.Som.load(model)
    assert (som.rows, som.cols, som.columns) == (10, 10, ["tf_bins"])
    nodes = som.winners(f)
    assert (nodes // 10).tolist() == f["bmu_row"].to_list()
    assert (nodes % 10).tolist() == f["bmu_col"].to_list()
    assert som.predict(f).tolist() == f["node_label"].to_list()
    # The distances are the command line's, and their mean is the quantisation error.
    x = np.vstack(f["tf_bins"].to_numpy()).astype(np.float64)
    _, dist = som._model.bmu(x)
    np.testing.assert_allclose(dist, f["bmu_distance"].to_numpy(), rtol=1e-12)
    assert som.quantization_error(f) == pytest.approx(dist.mean(), rel=1e-12)
    # The U-matrix from the codebook, recomputed here: mean distance to 4-neighbours.
    w = som.codebook
    u = np.zeros((10, 10))
    for r in range(10):
        for c in range(10):
            nb = [(r + dr, c + dc) for dr, dc in ((-1, 0), (1, 0), (0, -1), (0, 1)) if 0 <= r + dr < 10 and 0 <= c + dc < 10]
            u[r, c] = np.mean([np.linalg.norm(w[r, c] - w[a, b]) for a, b in nb])
    np.testing.assert_allclose(som.umatrix(), u, rtol=1e-10)


def test_a_map_python_trained_is_read_by_the_command_line(tmp_path: Path, labelled_features) -> None:
    feats, _ = labelled_features
    f = pl.read_parquet(feats).filter(pl.col("tf_bins").is_not_null())
    train = f.filter(pl.col("hit") % 2 == 0)
    som = aepipe.Som(6, 8, seed=7).fit(train, labels="criteria_label")
    assert som.labels.shape == (6, 8)
    # Training is seeded: the same data give the same map bit for bit.
    again = aepipe.Som(6, 8, seed=7).fit(train, labels="criteria_label")
    np.testing.assert_array_equal(som.codebook, again.codebook)
    som.save(tmp_path / "py-model")
    aepipe_cli("som", "classify", tmp_path / "py-model", feats, "--out", tmp_path / "cls", "--read-erroneous", "map")
    cls = pl.read_parquet(tmp_path / "cls" / "classification.parquet")
    joined = f.join(cls.select(KEY + ["node_label", "bmu_row", "bmu_col"]), on=KEY)
    assert joined.height == f.height
    assert som.predict(joined).tolist() == joined["node_label"].to_list()
    nodes = som.winners(joined)
    assert nodes.tolist() == (joined["bmu_row"] * 8 + joined["bmu_col"]).to_list()
    # And back: the folder loads into the same map.
    back = aepipe.Som.load(tmp_path / "py-model")
    np.testing.assert_array_equal(back.codebook, som.codebook)
    assert back.predict(f).tolist() == som.predict(f).tolist()
    # A map of mechanisms learnt on half the hits labels the other half mostly as the
    # criteria do (held out: the odd hits were not trained on).
    test = f.filter(pl.col("hit") % 2 == 1).filter(pl.col("criteria_label").is_in(["bond_failure", "fibre_failure"]))
    agree = (som.predict(test) == np.array(test["criteria_label"].to_list(), dtype=object)).mean()
    assert agree > 0.9, agree


def test_a_map_of_plain_arrays_without_labels_and_standardised(tmp_path: Path) -> None:
    rng = np.random.default_rng(3)
    # Two clusters far apart: no node may take rows of both.
    x = np.vstack([rng.normal(0, 0.1, (200, 3)), rng.normal(5, 0.1, (200, 3))])
    som = aepipe.Som(4, 4, seed=1).fit(x)
    nodes = som.predict(x)  # unlabelled: node indices
    assert nodes.dtype == np.int64
    assert not set(nodes[:200]) & set(nodes[200:])
    assert som.topographic_error(x) < 0.2
    with pytest.raises(ValueError, match="columns"):
        som.save(tmp_path / "m")  # 3 columns: the map cannot name them itself
    lab = ["low"] * 200 + ["high"] * 200
    s2 = aepipe.Som(4, 4, seed=1, columns=["a", "b", "c"], standardise=True).fit(x * [1, 100, 1e4], labels=lab)
    assert (s2.predict(x * [1, 100, 1e4]) == np.array(lab, dtype=object)).all()
    s2.save(tmp_path / "m2")
    back = aepipe.Som.load(tmp_path / "m2")
    assert back.standardise and back.columns == ["a", "b", "c"]
    np.testing.assert_array_equal(back.winners(x * [1, 100, 1e4]), s2.winners(x * [1, 100, 1e4]))
    # A row with a NaN is left out, not guessed.
    y = x[:3].copy()
    y[1, 0] = np.nan
    assert som.winners(y)[1] == -1


def test_trend_equals_the_command_line_and_scipys_linregress(tmp_path: Path, labelled_features) -> None:
    stats = need_module("scipy.stats")
    feats, _ = labelled_features
    aepipe_cli("trend", feats, "--out", tmp_path / "t", "--cutoff", "none", "--no-plots")
    theirs = pl.read_parquet(tmp_path / "t" / "trend.parquet")
    f = pl.read_parquet(feats)
    ours = aepipe.trend(f, cutoff="none")  # through a frame
    assert ours.equals(theirs)
    assert aepipe.trend(feats, cutoff="none").equals(theirs)  # through the path
    # Every power ratio's line against the AE number, as SciPy fits it.
    s = f.sort("hit")
    x = np.arange(1, s.height + 1, dtype=float)
    checked = 0
    for row in ours.iter_rows(named=True):
        y = s[row["column"]].to_numpy().astype(float)
        ok = np.isfinite(y)
        if row["r"] is None or ok.sum() < 3:
            continue
        ref = stats.linregress(x[ok], y[ok])
        assert row["n"] == ok.sum()
        assert row["r"] == pytest.approx(ref.rvalue, rel=1e-9, abs=1e-12)
        assert row["slope"] == pytest.approx(ref.slope, rel=1e-9, abs=1e-15)
        assert row["intercept"] == pytest.approx(ref.intercept, rel=1e-9, abs=1e-15)
        assert row["p"] == pytest.approx(ref.pvalue, rel=1e-6, abs=1e-300)
        checked += 1
    assert checked >= 20
    # Only some columns, and the first N hits.
    part = aepipe.trend(f, cutoff="hits:40", columns=["pr_200_300khz", "peak_freq_hz"])
    assert sorted(part["column"].to_list()) == ["peak_freq_hz", "pr_200_300khz"]
    assert set(part["n"].to_list()) == {40}


def test_novelty_flags_a_cloud_the_map_never_saw_and_few_fresh_draws_of_its_own() -> None:
    rng = np.random.default_rng(11)
    train = np.vstack([rng.normal(0, 0.3, (150, 4)), rng.normal(3, 0.3, (150, 4))])
    som = aepipe.Som(5, 5, seed=2).fit(train)
    t = som.novelty_threshold(0.99)
    assert t is not None and t > 0
    # The threshold is calibrated on held-out rows: above the training rows' own mean.
    assert t > som.quantization_error(train)
    assert som.novelty_threshold(1.0) >= t >= som.novelty_threshold(0.5)
    fresh = np.vstack([rng.normal(0, 0.3, (1000, 4)), rng.normal(3, 0.3, (1000, 4))])
    assert som.novel(fresh).sum() <= 60  # ~1 % expected of 2000
    far = rng.normal(-4, 0.3, (200, 4))
    assert som.novel(far).all()
    np.testing.assert_array_equal(som.distances(far) > t, som.novel(far))
    with pytest.raises(ValueError, match="quantile"):
        som.novelty_threshold(0.0)
    # Too few rows to hold any out: no calibration, and it says so.
    assert aepipe.Som(2, 2, seed=1).fit(train[:8]).novelty_threshold(0.99) is None
