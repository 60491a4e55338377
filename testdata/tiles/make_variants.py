#!/usr/bin/env python3
"""Writes hand-edited variants of a producer's tileset.json (standard library only).

The content files (.pnts, .glb) stay exactly as the producer wrote them; only the tree in
tileset.json is rearranged. Run from this folder: `python3 make_variants.py simple_pnts simple_glb`.

For a folder holding a py3dtiles-shaped tileset (root with a preview content and one child `r`
whose children are the leaves r0, r2, ...), it writes:

- tileset_add.json: refinement ADD, the leaf contents spread over three levels (the first leaf
  on the child, the second with the third as its child, the rest as leaves), so that all tiles
  together hold every source point once. The preview and `r` contents are left out.
- tileset_rotated.json: REPLACE as the original, with one more level: the root's transform is
  the original one times a rotation of 30 degrees about z, a new tile under it undoes the
  rotation (and carries the preview), and the original child hangs below that. World positions
  are the original ones, reached through three nested transforms.
- tileset_external.json + external/subtree.json: the original child `r` with its subtree moved
  into an external tileset one folder down (its content URIs rewritten to `../...`), referenced
  from a tile of the root without a transform of its own.
"""
import copy
import os
import json
import math
import sys


def rotation_z(deg):
    c, s = math.cos(math.radians(deg)), math.sin(math.radians(deg))
    # column-major 4x4
    return [c, s, 0, 0, -s, c, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1]


def mul(a, b):
    """Column-major 4x4 product a*b."""
    return [sum(a[k * 4 + r] * b[c * 4 + k] for k in range(4)) for c in range(4) for r in range(4)]


def apply_box(m, box):
    """A box [c, x, y, z] mapped by the column-major affine m."""
    c = box[0:3]
    out = [sum(m[k * 4 + r] * c[k] for k in range(3)) + m[12 + r] for r in range(3)]
    for a in range(3):
        v = box[3 + 3 * a:6 + 3 * a]
        out += [sum(m[k * 4 + r] * v[k] for k in range(3)) for r in range(3)]
    return out


def write(path, tileset):
    with open(path, "w") as f:
        json.dump(tileset, f, indent=1)
        f.write("\n")


def variants(folder):
    with open(f"{folder}/tileset.json") as f:
        original = json.load(f)
    root = original["root"]
    (child,) = root["children"]
    leaves = child["children"]

    # ADD: every source point once, over three levels.
    add = copy.deepcopy(original)
    a_root = add["root"]
    a_root["refine"] = "ADD"
    del a_root["content"]
    a_child = copy.deepcopy(child)
    a_child["refine"] = "ADD"
    first, second, third, *rest = copy.deepcopy(leaves)
    a_child["content"] = first["content"]
    second["refine"] = "ADD"
    second["boundingVolume"] = copy.deepcopy(child["boundingVolume"])
    second["children"] = [third]
    a_child["children"] = [second] + rest
    a_root["children"] = [a_child]
    write(f"{folder}/tileset_add.json", add)

    # Nested transforms with a rotation that a middle tile undoes.
    rot = copy.deepcopy(original)
    r_root = rot["root"]
    r_root["transform"] = mul(root["transform"], rotation_z(30.0))
    r_root["boundingVolume"] = {"box": apply_box(rotation_z(-30.0), root["boundingVolume"]["box"])}
    middle = {
        "boundingVolume": copy.deepcopy(root["boundingVolume"]),
        "geometricError": root["geometricError"],
        "transform": rotation_z(-30.0),
        "content": r_root.pop("content"),
        "children": r_root["children"],
    }
    r_root["children"] = [middle]
    write(f"{folder}/tileset_rotated.json", rot)

    # External tileset one folder down.
    ext = copy.deepcopy(original)
    sub_root = copy.deepcopy(child)
    sub_root["content"]["uri"] = "../" + sub_root["content"]["uri"]
    for leaf in sub_root["children"]:
        leaf["content"]["uri"] = "../" + leaf["content"]["uri"]
    subtree = {
        "asset": copy.deepcopy(original["asset"]),
        "geometricError": child["geometricError"],
        "root": sub_root,
    }

    os.makedirs(f"{folder}/external", exist_ok=True)
    write(f"{folder}/external/subtree.json", subtree)
    ext["root"]["children"] = [
        {
            "boundingVolume": {"box": apply_box(child["transform"], child["boundingVolume"]["box"])},
            "geometricError": child["geometricError"],
            "content": {"uri": "external/subtree.json"},
        }
    ]
    write(f"{folder}/tileset_external.json", ext)


if __name__ == "__main__":
    for folder in sys.argv[1:]:
        variants(folder)
