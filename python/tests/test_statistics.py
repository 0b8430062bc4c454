"""The energy power law of `aepipe statistics` (issue 39, part 5) against the `powerlaw`
package (Alstott et al. 2014): the same α at the same x_min, and a known exponent recovered
from 10⁵ draws."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import polars as pl

from conftest import aepipe_cli, need_module


def test_energy_power_law_equals_the_powerlaw_packages(tmp_path: Path) -> None:
    powerlaw = need_module("powerlaw")
    rng = np.random.default_rng(5)
    alpha = 1.7
    # A power law above 2e3 eu under a body that is not one (uniform below).
    tail = 2e3 * (1 - rng.random(100_000)) ** (-1 / (alpha - 1))
    body = rng.uniform(100, 2e3, 30_000)
    e = np.concatenate([body, tail])
    f = tmp_path / "features.parquet"
    pl.DataFrame(
        {
            "experiment": ["pl"] * len(e),
            "channel": np.ones(len(e), dtype=np.int32),
            "hit": np.arange(1, len(e) + 1, dtype=np.int64),
            "energy_eu": e,
        }
    ).write_parquet(f)
    aepipe_cli("statistics", f, "--out", tmp_path / "s")
    s = pl.read_parquet(tmp_path / "s" / "statistics.parquet").row(0, named=True)
    assert s["n_energy"] == len(e)
    # Recovered within ±0.02 of the stated exponent, x_min near the body's end.
    assert abs(s["energy_alpha"] - alpha) < 0.02, s
    assert 1.5e3 < s["energy_x_min_eu"] < 3e3, s
    # The powerlaw package at aepipe's x_min: the same α and standard error.
    fit = powerlaw.Fit(e, xmin=s["energy_x_min_eu"], discrete=False, verbose=False)
    assert abs(fit.power_law.alpha - s["energy_alpha"]) < 1e-6, (fit.power_law.alpha, s)
    se = getattr(fit.power_law, "standard_err", None) or fit.power_law.sigma
    assert abs(se - s["energy_alpha_se"]) < 1e-6
    assert s["energy_n_tail"] == int((e >= s["energy_x_min_eu"]).sum())
    assert abs(s["energy_cumulative_exponent"] - (s["energy_alpha"] - 1)) < 1e-12
