"""Reading recordings: hit rows and waveforms of any input the command line reads."""

from __future__ import annotations

from typing import Iterator

import polars as pl

from . import _aepipe
from ._aepipe import Record
from ._common import Paths, PathLike, config_arg, paths_arg, warn_rejects


def read_hits(
    paths: Paths, *, config: PathLike | None = None, progress: bool = False
) -> pl.DataFrame:
    """The hit rows (``hits.parquet``'s columns) of any readable input.

    ``paths`` is a file or folder, or a list of them, as on the command line (Vallen
    ``.pridb``/``.tradb``, MISTRAS ``.DTA``, AEwin, WaveExplorer, WAV, CSV, Parquet);
    ``config`` an optional pipeline TOML (its ``[ingest]`` keys). Every hit of a Vallen
    ``.pridb`` is a row, with or without a transient. Records that cannot be read are named
    in a warning (the command line's ``rejects.parquet``).

    >>> import aepipe
    >>> hits = aepipe.read_hits("../shared/data/real/vallen/steel_plate")  # doctest: +SKIP
    >>> hits.select("channel", "time_s", "amplitude_db").head(3)            # doctest: +SKIP
    """
    stream, rejects = _aepipe.read_hits(paths_arg(paths), config_arg(config), progress)
    warn_rejects(rejects)
    return pl.DataFrame(stream)


def read_waveforms(
    paths: Paths, *, config: PathLike | None = None, progress: bool = False
) -> pl.DataFrame:
    """One row per waveform record (``waveforms.parquet``'s columns), the samples in volts
    as the list column ``samples_v``.

    >>> w = aepipe.read_waveforms("../shared/data/real/vallen/bearing")   # doctest: +SKIP
    >>> x = w["samples_v"][0].to_numpy()                                  # doctest: +SKIP
    """
    stream, rejects = _aepipe.read_waveforms(paths_arg(paths), config_arg(config), progress)
    warn_rejects(rejects)
    return pl.DataFrame(stream)


def iter_waveforms(
    paths: Paths, *, config: PathLike | None = None, batch_size: int = 256
) -> Iterator[Record]:
    """The waveform records one by one, reading ``batch_size`` at a time: memory stays
    bounded whatever the size of the inputs.

    Each :class:`Record` has ``experiment``, ``channel``, ``hit``, ``time_s``,
    ``sample_rate_hz``, ``pretrigger_samples`` and ``samples`` (float32 NumPy, volts).
    Leaving the loop early releases the files; rejects are named in a warning at the end.

    >>> for r in aepipe.iter_waveforms("recordings/", batch_size=64):    # doctest: +SKIP
    ...     print(r.hit, r.samples.max())
    """
    # Opened here, so that a bad path or batch size raises at the call, not at the first
    # record.
    it = _aepipe.iter_waveforms(paths_arg(paths), config_arg(config), batch_size)
    return _records(it)


def _records(it: _aepipe.WaveformIter) -> Iterator[Record]:
    try:
        yield from it
    finally:
        it.close()
        warn_rejects(it.rejects, stacklevel=4)
