"""Print what vallenae reads of every transient of a .tradb, as JSON, for comparing
salvaged transients with it (tests/it/salvage.rs): per record its TRAI, channel, sample
count, the first and last 32 samples (V) and the sum and sum of squares of all of them.

usage: python3 vallenae_tradb.py FILE.tradb
"""
import json
import sys

try:
    import vallenae as vae
except ImportError as e:
    print(f"missing: {e}", file=sys.stderr)
    sys.exit(3)

out = []
with vae.io.TraDatabase(sys.argv[1]) as tra:
    for rec in tra.iread():
        d = [float(v) for v in rec.data]
        out.append({"trai": int(rec.trai), "channel": int(rec.channel), "n": len(d),
                    "first": d[:32], "last": d[-32:], "sum": sum(d),
                    "sumsq": sum(v * v for v in d)})
print(json.dumps(out))
