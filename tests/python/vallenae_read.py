"""Print what vallenae sees in a .pridb/.tradb pair, as JSON: the hits (channel, trai,
time) and the first 64 samples of each transient. Used by tests/it/e2e.rs.

usage: python3 vallenae_read.py STEM   (STEM.pridb and STEM.tradb)
"""
import json
import sys

import vallenae as vae

stem = sys.argv[1]
with vae.io.PriDatabase(stem + ".pridb") as pri:
    hits = pri.read_hits()
with vae.io.TraDatabase(stem + ".tradb") as tra:
    out = []
    for rec in tra.iread():
        out.append({"trai": int(rec.trai), "channel": int(rec.channel), "time": float(rec.time),
                    "samplerate": float(rec.samplerate), "pretrigger": int(rec.pretrigger),
                    "n": int(len(rec.data)), "first": [float(v) for v in rec.data[:64]]})
print(json.dumps({"hits": int(len(hits)), "hit_trai": [int(v) for v in hits["trai"].tolist()],
                  "transients": out}))
