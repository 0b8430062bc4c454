"""The four vallenae 0.14 time pickers on every transient of .tradb files, as vallenae reads
them (float32 volts): JSON {stem: [[trai, channel, hinkley, aic, er, mer], ...]}.

usage: python3 vallenae_picks.py FILE.tradb ...
"""
import json
import sys
from pathlib import Path

import vallenae as vae
from vallenae.timepicker import aic, energy_ratio, hinkley, modified_energy_ratio

out = {}
for path in sys.argv[1:]:
    rows = []
    with vae.io.TraDatabase(path) as tra:
        for rec in tra.iread():
            x = rec.data
            assert x.dtype.name == "float32", x.dtype
            n = len(x)
            er = energy_ratio(x)[1] if n > 200 else None
            mer = modified_energy_ratio(x)[1] if n > 200 else None
            rows.append([int(rec.trai), int(rec.channel), int(hinkley(x)[1]), int(aic(x)[1]), er, mer])
    out[Path(path).stem] = rows
print(json.dumps(out))
