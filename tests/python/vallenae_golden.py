"""Regenerate tests/golden/vallenae_hit_features.csv: hit features of the MIT-licensed Vallen
example recordings (../shared/data/real/vallen/) computed with vallenae's own functions.

    pip install "vallenae==0.14.*"
    python3 tests/python/vallenae_golden.py ../shared/data/real/vallen tests/golden/vallenae_hit_features.csv

vallenae reads the waveforms (raw volts, FLAC decoded by vallenae) and the threshold of each
record; the features are vallenae.features.acoustic_emission's peak_amplitude, rise_time,
energy, signal_strength, counts and rms. vallenae has no duration function: duration is
first to last sample with |x| >= threshold (ASTM E1316), computed here with numpy.
The integration test `hit_features_agree_with_vallenae` compares aepipe against this file.
"""
import csv
import pathlib
import sys

import numpy as np
import vallenae as vae
from vallenae.features import acoustic_emission as fe

root = pathlib.Path(sys.argv[1])
out = pathlib.Path(sys.argv[2])
rows = []
for tradb in sorted(root.rglob("*.tradb")):
    with vae.io.TraDatabase(str(tradb)) as db:
        for rec in db.iread():
            x = np.asarray(rec.data, dtype=np.float64)
            fs = rec.samplerate
            thr = rec.threshold  # volts
            above = np.flatnonzero(np.abs(x) >= thr)
            duration = (above[-1] - above[0]) / fs if above.size else 0.0
            rows.append({
                "file": tradb.name,
                "trai": rec.trai,
                "channel": rec.channel,
                "samples": len(x),
                "threshold_v": repr(float(thr)),
                "amplitude_db": repr(float(20 * np.log10(fe.peak_amplitude(x) / 1e-6))),
                "rise_time_s": repr(float(fe.rise_time(x, thr, fs))),
                "duration_s": repr(float(duration)),
                "counts": int(fe.counts(x, thr)),
                "energy_eu": repr(float(fe.energy(x, fs))),
                "signal_strength_nvs": repr(float(fe.signal_strength(x, fs))),
                "rms_v": repr(float(fe.rms(x))),
            })
with open(out, "w", newline="") as f:
    w = csv.DictWriter(f, fieldnames=list(rows[0].keys()))
    w.writeheader()
    w.writerows(rows)
print(f"{len(rows)} records -> {out}")
