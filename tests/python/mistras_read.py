"""Read a MISTRAS .DTA with MistrasDTA (the independent reader on PyPI) and print JSON:
the hits (time, channel and every feature MistrasDTA decodes) and the waveforms (time,
channel, sample rate, TDLY, samples in volts).

Used by tests/it/dta.rs. MistrasDTA stores each waveform as a byte string, which numpy
truncates at trailing NUL bytes: the number of samples it gives can fall short of the
message's, so the test compares the samples it has.
"""
import json
import sys

import numpy as np
from MistrasDTA import read_bin

rec, wfm = read_bin(sys.argv[1])
hits = []
for r in rec:
    d = {name: float(r[name]) for name in rec.dtype.names if name != "TIMESTAMP"}
    hits.append(d)
waves = []
for w in wfm:
    v = np.frombuffer(w["WAVEFORM"][: len(w["WAVEFORM"]) // 8 * 8], dtype=np.float64)
    waves.append({
        "time": float(w["SSSSSSSS.mmmuuun"]),
        "ch": int(w["CH"]),
        "srate": float(w["SRATE"]),
        "tdly": int(w["TDLY"]),
        "v": v.tolist(),
    })
print(json.dumps({"hits": hits, "waves": waves}))
