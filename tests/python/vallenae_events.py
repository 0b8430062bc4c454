"""vallenae 0.14's EventBuilder on .pridb files: JSON list, one entry per case, each a list
of events [time_s, [channels], close_reason, [hit times]].

usage: python3 vallenae_events.py CASES.json
CASES.json: [{"pridb": PATH, "fhcdt": s, "dt1x": s, "dtnx": s, "allow_duplicates": bool,
              "roles": {"CH": "guard" | "unused" | "combined"}}, ...]
A channel not in "roles" is normal (vallenae's mapping form makes unlisted channels unused,
so the mapping is completed with every channel of the file).
"""
import json
import sys

import vallenae as vae
from vallenae.processor import ChannelFunction, EventBuilder

cases = json.load(open(sys.argv[1]))
out = []
for c in cases:
    with vae.io.PriDatabase(c["pridb"]) as pri:
        hits = list(pri.iread_hits())
    roles = {int(k): v for k, v in c.get("roles", {}).items()}
    name = {"guard": ChannelFunction.GUARD, "unused": ChannelFunction.UNUSED,
            "combined": ChannelFunction.COMBINED}
    channels = {h.channel: name[roles[h.channel]] if h.channel in roles else ChannelFunction.NORMAL
                for h in hits}
    b = EventBuilder(fhcdt=c["fhcdt"], dt1x_max=c["dt1x"], dtnx_max=c["dtnx"], channels=channels,
                     allow_multiple_hits_per_channel=c.get("allow_duplicates", False))
    events = [[e.time, e.channel_sequence, e.close_reason.name.lower(), [h.time for h in e.hits]]
              for e in b.process_all(hits)]
    out.append(events)
print(json.dumps(out))
