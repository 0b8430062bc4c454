"""Argument handling shared by the public functions (not part of the API)."""

from __future__ import annotations

import os
import warnings
from typing import Sequence, Union

import numpy as np

PathLike = Union[str, "os.PathLike[str]"]
Paths = Union[PathLike, Sequence[PathLike]]


def f32_1d(arr: object) -> np.ndarray:
    """One signal as a contiguous 1-D float32 array (the samples' type in aepipe's core)."""
    return np.ascontiguousarray(np.asarray(arr).ravel(), dtype=np.float32)


def paths_arg(paths: Paths) -> list[str]:
    """One path or a list of them, as strings (files or folders, as on the command line)."""
    if isinstance(paths, (str, os.PathLike)):
        return [os.fspath(paths)]
    out = [os.fspath(p) for p in paths]
    if not out:
        raise ValueError("no input paths given")
    return out


def is_paths(data: object) -> bool:
    """Whether ``data`` is a path or a non-empty sequence of paths."""
    if isinstance(data, (str, os.PathLike)):
        return True
    return (
        isinstance(data, Sequence)
        and len(data) > 0
        and all(isinstance(p, (str, os.PathLike)) for p in data)
    )


def config_arg(config: PathLike | None) -> str | None:
    return None if config is None else os.fspath(config)


def warn_rejects(rejects: list[tuple[str, str, str, str]], stacklevel: int = 3) -> None:
    """Nothing is lost silently: records that could not be read are named in a warning."""
    if rejects:
        file, record, stage, reason = rejects[0]
        more = f" (and {len(rejects) - 1} more)" if len(rejects) > 1 else ""
        warnings.warn(
            f"aepipe: {len(rejects)} record(s) rejected{more}; first: {file} {record} "
            f"[{stage}]: {reason}",
            stacklevel=stacklevel,
        )
