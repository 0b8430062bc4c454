"""Whole jobs: a simulation, a reference library, and the whole method (``aepipe run``)."""

from __future__ import annotations

import json
import os
from typing import Any

import polars as pl

from . import _aepipe
from ._common import Paths, PathLike, paths_arg


def simulate(scenario: str | PathLike, **params: float) -> pl.DataFrame:
    """One run of the hybrid vibro-acoustic simulator (ch. 3–4): the sensors' signals as
    ``waveforms.parquet`` rows (one per sensor; samples in volts, recorded like an AE system
    with trigger, pretrigger and noise), with the scenario and its parameters.

    ``scenario`` is a built-in name (``mesh3x3-bond-failure``, ``structure2x1-fibre-failure``,
    …) or the path of a model file (the thesis's Appendix-A sections, or TOML); ``params``
    override the scenario's values as ``aepipe simulate --param KEY=VALUE`` does (a key the
    scenario does not read is a :class:`SimError` naming it and the keys it reads).

    >>> w = aepipe.simulate("structure2x1-fibre-failure", point=7)   # doctest: +SKIP
    >>> aepipe.features(w["samples_v"].to_list()[0], sample_rate_hz=w["sample_rate_hz"][0])  # doctest: +SKIP
    """
    pairs = [(str(k), float(v)) for k, v in params.items()]
    s = os.fspath(scenario)
    if os.path.exists(s):
        stream, _lines = _aepipe.simulate(None, pairs, s)
    else:
        stream, _lines = _aepipe.simulate(s, pairs, None)
    return pl.DataFrame(stream)


def reference_library(
    path_or_none: PathLike | None = None, *, threads: int | None = None, progress: bool = False
) -> pl.DataFrame:
    """A labelled reference library: the simulator over a grid of scenarios × parameters ×
    material draws × sensors (``pipelines/reference-library.toml``'s format; ``None``: the
    embedded library the demo trains on), as ``waveforms.parquet`` rows with their
    mechanism in ``label`` (bond_failure, fibre_failure, erroneous).

    >>> lib = aepipe.reference_library(threads=2)                       # doctest: +SKIP
    >>> lib.group_by("label").len()                                     # doctest: +SKIP
    """
    p = None if path_or_none is None else os.fspath(path_or_none)
    return pl.DataFrame(_aepipe.reference_library(p, threads, progress))


def run(
    config: PathLike,
    inputs: Paths,
    out: PathLike,
    *,
    truth: PathLike | None = None,
    threads: int | None = None,
    progress: bool = False,
) -> dict[str, Any]:
    """The whole method from a pipeline definition, as ``aepipe run --config CONFIG INPUTS
    --out OUT``: features, events, trend, SOM, classification, damage profile, evolution and
    ``OUT/report.html``. Returns the run's summary: ``report`` (the report's path),
    ``tables`` (every table written), ``counts``, ``trend_significant``, ``som``,
    ``truth`` (with ``truth=``, the scores against it), ``seconds`` and the ``headline``
    lines the command line prints.

    >>> s = aepipe.run("pipelines/notched-paper.toml", "recordings/", "out/run")  # doctest: +SKIP
    >>> s["report"]                                                              # doctest: +SKIP
    'out/run/report.html'
    """
    text = _aepipe.run(
        os.fspath(config),
        paths_arg(inputs),
        os.fspath(out),
        None if truth is None else os.fspath(truth),
        threads,
        progress,
    )
    return json.loads(text)
