"""The NumPy peer of `aepipe bench detect`: the same cut (threshold, ddt, rearm, maximum
duration) on the same int16 stream, the crossings found by NumPy and the rules applied
crossing by crossing. Prints `numpy <seconds> <hits>` for the cut alone (the load excluded).
"""

import sys
import time

import numpy as np


def cut(x: np.ndarray, thr: float, ddt: int, rearm: int, maxd: int) -> list:
    cross = np.flatnonzero(np.abs(x.astype(np.int32)) >= thr)
    out, i, n = [], 0, len(cross)
    while i < n:
        first = last = int(cross[i])
        i += 1
        while i < n and cross[i] <= min(last + ddt, first + maxd - 1):
            last = int(cross[i])
            i += 1
        end = min(last + ddt, first + maxd)
        out.append((first, last))
        # Skip the blind time by search, not by stepping.
        i = int(np.searchsorted(cross, end + rearm, side="right"))
    return out


def main() -> None:
    path, thr = sys.argv[1], float(sys.argv[2])
    x = np.load(path)
    t0 = time.perf_counter()
    hits = cut(x, thr, 2000, 1000, 100_000)
    print(f"numpy {time.perf_counter() - t0:.6f} {len(hits)}")


if __name__ == "__main__":
    main()
