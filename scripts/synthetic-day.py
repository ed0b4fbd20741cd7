#!/usr/bin/env python3
"""A synthetic day of OpenStreetMap changes over a region, as a replication feed folder.

Usage: synthetic-day.py REGION.osm.pbf OUT_DIR [HOURS]
Needs pyosmium (`pip install osmium`, in a venv). Writes OUT_DIR/state.txt and one
AAA/BBB/CCC.osc.gz (with its .state.txt) per hour, sequences 1 to HOURS (default 24), a feed
`citymesh replicate --url` follows once OUT_DIR is served over HTTP. Over the day, with a fixed
seed, as many edits as a busy city sees in OSM: 1 % of the building ways get a new height, 0.2 %
have one node moved by about a metre, 0.02 % are deleted, and as many new 10 x 7 m buildings are
added beside existing ones (on new nodes). The edits are spread evenly over the hours.
"""
import gzip
import os
import random
import sys
from xml.sax.saxutils import quoteattr

import osmium

src, out = sys.argv[1], sys.argv[2]
hours = int(sys.argv[3]) if len(sys.argv) > 3 else 24
rng = random.Random(20261207)
ways, nodes_used = [], set()


class Ways(osmium.SimpleHandler):
    def way(self, w):
        if "building" in w.tags and len(w.nodes) >= 4 and w.nodes[0].ref == w.nodes[-1].ref:
            ways.append((w.id, [n.ref for n in w.nodes], {t.k: t.v for t in w.tags}))


Ways().apply_file(src)
rng.shuffle(ways)
n = len(ways)
heights = ways[: n // 100]
moves = ways[n // 100 : n // 100 + n // 500]
deletes = ways[n // 100 + n // 500 : n // 100 + n // 500 + n // 5000]
adds = ways[n // 100 + n // 500 + n // 5000 : n // 100 + n // 500 + 2 * (n // 5000)]
for _, refs, _ in moves + adds:
    nodes_used.update(refs)
loc = {}


class Nodes(osmium.SimpleHandler):
    def node(self, o):
        if o.id in nodes_used:
            loc[o.id] = (o.location.lon, o.location.lat)


Nodes().apply_file(src)


def way_xml(wid, refs, tags):
    nd = "".join(f'<nd ref="{r}"/>' for r in refs)
    tg = "".join(f"<tag k={quoteattr(k)} v={quoteattr(v)}/>" for k, v in sorted(tags.items()))
    return f'<way id="{wid}" version="2">{nd}{tg}</way>'


next_node, next_way = 90_000_000_000, 9_000_000_000
for h in range(hours):
    part = lambda xs: xs[h * len(xs) // hours : (h + 1) * len(xs) // hours]
    create, modify, delete = [], [], []
    for wid, refs, tags in part(heights):
        tags = dict(tags, height=f"{rng.uniform(4, 40):.1f}")
        modify.append(way_xml(wid, refs, tags))
    for wid, refs, tags in part(moves):
        r = refs[rng.randrange(len(refs) - 1)]
        lon, lat = loc[r]
        modify.append(f'<node id="{r}" version="2" lat="{lat + 0.00001:.7f}" lon="{lon + 0.00001:.7f}"/>')
    for wid, refs, tags in part(deletes):
        delete.append(f'<way id="{wid}" version="2"/>')
    for wid, refs, tags in part(adds):
        lon, lat = loc[refs[0]]
        lon, lat = lon + 0.0004, lat + 0.0003
        ids = []
        for dx, dy in ((0, 0), (0.000137, 0), (0.000137, 0.000063), (0, 0.000063)):
            next_node += 1
            ids.append(next_node)
            create.append(f'<node id="{next_node}" version="1" lat="{lat + dy:.7f}" lon="{lon + dx:.7f}"/>')
        next_way += 1
        create.append(way_xml(next_way, ids + ids[:1], {"building": "yes", "height": "6"}))
    seq = h + 1
    body = (
        '<?xml version="1.0" encoding="UTF-8"?>\n<osmChange version="0.6" generator="synthetic-day">'
        + f"<create>{''.join(create)}</create><modify>{''.join(modify)}</modify>"
        + f"<delete>{''.join(delete)}</delete></osmChange>\n"
    )
    path = os.path.join(out, f"{seq // 1000000:03d}", f"{seq // 1000 % 1000:03d}")
    os.makedirs(path, exist_ok=True)
    state = f"sequenceNumber={seq}\ntimestamp=2026-12-07T{h:02d}\\:00\\:00Z\n"
    with gzip.open(os.path.join(path, f"{seq % 1000:03d}.osc.gz"), "wt") as f:
        f.write(body)
    with open(os.path.join(path, f"{seq % 1000:03d}.state.txt"), "w") as f:
        f.write(state)
    with open(os.path.join(out, "state.txt"), "w") as f:
        f.write(state)
print(f"{n} building ways; {len(heights)} heights, {len(moves)} nodes moved, {len(deletes)} deleted, {len(adds)} added over {hours} diffs in {out}")
