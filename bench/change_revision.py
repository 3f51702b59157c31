#!/usr/bin/env python3
"""Makes the next revision of a plant in plantview XML (docs/xml-format.md) for change images
and incremental farms: moves a share of the equipment along x and adds straight pipes beside the
first moved item. Deterministic: the equipment moved is every Nth in file order.

    bench/change_revision.py IN.xml OUT.xml [--move-share 0.01] [--move-m 2.0] [--add-pipes 20]

Prints what it changed as JSON (the ids, as the store's `changes` lists them)."""
import argparse
import hashlib
import json
import math
import re
import sys


def main():
    p = argparse.ArgumentParser()
    p.add_argument("input")
    p.add_argument("output")
    p.add_argument("--move-share", type=float, default=0.01)
    p.add_argument("--move-m", type=float, default=2.0)
    p.add_argument("--add-pipes", type=int, default=20)
    a = p.parse_args()
    text = open(a.input, encoding="utf-8").read()
    heads = list(re.finditer(r'<object id="([0-9a-f]+)" name="([^"]*)" class="equipment"[^>]*>', text))
    count = max(1, math.ceil(a.move_share * len(heads))) if heads else 0
    step = max(1, len(heads) // max(count, 1))
    chosen = heads[::step][:count]
    moved, first_origin, source = [], None, None
    out, last = [], 0
    for m in chosen:
        head = m.group(0)
        origin = re.search(r'origin_m="([^"]+)"', head)
        x, y, z = (float(v) for v in origin.group(1).split())
        if first_origin is None:
            first_origin = (x, y, z)
            source = re.search(r'source="([^"]*)"', head).group(1)
        new_head = head.replace(origin.group(0), 'origin_m="%r %r %r"' % (x + a.move_m, y, z))
        out.append(text[last:m.start()])
        out.append(new_head)
        last = m.end()
        moved.append({"id": str(int(m.group(1), 16)), "name": m.group(2)})
    out.append(text[last:])
    text = "".join(out)
    added = []
    pipes = []
    for k in range(a.add_pipes):
        name = "/NEW-PIPE-%02d" % (k + 1)
        object_id = hashlib.sha1((source + "\0" + name).encode()).hexdigest()[:16]
        x, y, z = first_origin
        ox, oy, oz = x - 3.0, y - 2.0 + 0.4 * k, z + 3.0
        pipes.append(
            '  <object id="%s" name="%s" class="pipe" colour="#20a040ff" origin_m="%r %r %r" source="%s">\n'
            '    <primitive kind="cylinder" radius_m="0.0762" height_m="6" linear="0 0 1 0 1 0 -1 0 0" translation_m="3 0 0"/>\n'
            '    <segment start_m="0 0 0" end_m="6 0 0" diameter_m="0.1524"/>\n'
            '  </object>\n' % (object_id, name, ox, oy, oz, source))
        added.append({"id": str(int(object_id, 16)), "name": name})
    end = text.rindex("</plantview>")
    text = text[:end] + "".join(pipes) + text[end:]
    open(a.output, "w", encoding="utf-8").write(text)
    json.dump({"equipment": len(heads), "moved": moved, "added": added}, sys.stdout)
    print()


if __name__ == "__main__":
    main()
