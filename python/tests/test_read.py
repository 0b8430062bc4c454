"""Reading recordings, against vallenae on the real Vallen files."""

from __future__ import annotations

import gc
from pathlib import Path

import numpy as np
import polars as pl

import aepipe
from conftest import need, need_module, real


def vallen_pridbs() -> list[Path]:
    files = sorted(real().glob("**/*.pridb"))
    need(len(files) >= 4, "expected the real Vallen sets")
    return files


def test_read_hits_equals_vallenae_on_every_real_vallen_file() -> None:
    vae = need_module("vallenae")
    for f in vallen_pridbs():
        ours = aepipe.read_hits(f)
        with vae.io.PriDatabase(str(f)) as db:
            theirs = db.read_hits()
        assert ours.height == len(theirs), f
        assert ours["channel"].to_list() == theirs["channel"].tolist(), f
        np.testing.assert_allclose(ours["time_s"].to_numpy(), theirs["time"].to_numpy(), rtol=0, atol=1e-9)
        # vallenae gives amplitudes in volts; the hit table in dB_AE (1 µV).
        db_ae = 20 * np.log10(theirs["amplitude"].to_numpy() / 1e-6)
        np.testing.assert_allclose(ours["amplitude_db"].to_numpy(), db_ae, rtol=0, atol=1e-6)
        tra = theirs["trai"].fillna(0).astype(int).tolist()
        assert [t or 0 for t in ours["trai"].to_list()] == tra, f


def test_read_waveforms_and_iter_waveforms_agree_and_iter_stops_half_way() -> None:
    folder = real("vallen", "bearing")
    frame = aepipe.read_waveforms(folder)
    recs = list(aepipe.iter_waveforms(folder, batch_size=7))
    assert frame.height == len(recs) == 490
    for i in (0, 123, 489):
        r = recs[i]
        row = frame.row(i, named=True)
        assert (r.experiment, r.channel, r.hit) == (row["experiment"], row["channel"], row["hit"])
        assert r.samples.dtype == np.float32
        np.testing.assert_array_equal(r.samples, np.asarray(row["samples_v"], dtype=np.float32))
        assert r.sample_rate_hz == row["sample_rate_hz"]
        assert r.pretrigger_samples == row["pretrigger_samples"]

    # Abandoning the iterator half-way, many times, holds no records or files: the
    # process's resident memory does not grow with the number of abandoned iterators.
    def rss_kib() -> int:
        with open("/proc/self/status") as s:
            return next(int(line.split()[1]) for line in s if line.startswith("VmRSS:"))

    def abandon() -> None:
        it = aepipe.iter_waveforms(folder, batch_size=16)
        for k, _ in enumerate(it):
            if k == 20:
                break
        del it

    for _ in range(5):
        abandon()
    gc.collect()
    before = rss_kib()
    for _ in range(60):
        abandon()
    gc.collect()
    grown = rss_kib() - before
    # 60 abandoned iterators each held 16 records of 5 000 samples (~20 kB each): kept,
    # they would add ~19 MiB.
    assert grown < 8 * 1024, f"RSS grew {grown} KiB over 60 abandoned iterators"


def test_the_pickers_give_vallenaes_values_and_index_on_real_records() -> None:
    tp = need_module("vallenae").timepicker
    records = [r for f in ("steel_plate", "bearing") for r in aepipe.iter_waveforms(real("vallen", f))]
    assert len(records) >= 400
    for r in records[::3]:
        x = r.samples
        for ours, theirs in (
            (aepipe.pickers.hinkley(x, alpha=5), tp.hinkley(x, 5)),
            (aepipe.pickers.hinkley(x, alpha=37), tp.hinkley(x, 37)),
            (aepipe.pickers.aic(x), tp.aic(x)),
            (aepipe.pickers.energy_ratio(x, win_len=80), tp.energy_ratio(x, 80)),
            (aepipe.pickers.modified_energy_ratio(x), tp.modified_energy_ratio(x)),
        ):
            assert ours[1] == theirs[1], (r.experiment, r.hit)
            assert ours[0].dtype == theirs[0].dtype, (ours[0].dtype, theirs[0].dtype)
            np.testing.assert_allclose(ours[0], theirs[0], rtol=1e-9, atol=0, equal_nan=True)


def test_read_hits_takes_one_path_a_list_and_pathlike() -> None:
    f = real("vallen", "steel_plate")
    one = aepipe.read_hits(f)
    both = aepipe.read_hits([str(f), real("vallen", "bearing")])
    assert both.height == one.height + aepipe.read_hits(real("vallen", "bearing")).height
    assert isinstance(one, pl.DataFrame) and {"experiment", "channel", "hit", "time_s"} <= set(one.columns)
