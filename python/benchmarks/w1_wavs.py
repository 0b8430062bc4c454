"""Write the peers' W1 signals as one float32 WAV file per hit (10 MHz, mono).

Usage: python w1_wavs.py PEERS/data/w1_signals_f32.bin OUT_DIR

The whole-process benchmark of docs/performance.md reads them with
`aepipe features OUT_DIR --out RUN --threads 1 --quiet` (651 WAV records, no pretrigger).
Standard library only: the standard `wave` module writes integer PCM, so the 44-byte
header of an IEEE-float WAV (format 3) is written here.
"""

import struct
import sys
from array import array
from pathlib import Path

N = 4096
FS = 10_000_000


def main() -> None:
    src, out = Path(sys.argv[1]), Path(sys.argv[2])
    samples = array("f")
    samples.frombytes(src.read_bytes())
    if sys.byteorder != "little":
        samples.byteswap()
    out.mkdir(parents=True, exist_ok=True)
    count = len(samples) // N
    for i in range(count):
        data = samples[i * N : (i + 1) * N].tobytes()
        header = (
            b"RIFF"
            + struct.pack("<I", 36 + len(data))
            + b"WAVEfmt "
            + struct.pack("<IHHIIHH", 16, 3, 1, FS, FS * 4, 4, 32)
            + b"data"
            + struct.pack("<I", len(data))
        )
        (out / f"hit{i + 1:04d}.wav").write_bytes(header + data)
    print(f"{count} WAV files in {out}")


if __name__ == "__main__":
    main()
