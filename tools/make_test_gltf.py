#!/usr/bin/env python3
"""Writes the small glTF files of tests/data/gltf (the glTF loader tests).

Each file exercises one thing the tests check by known answers: node
transforms, .glb, material-mapping precedence, skipped primitive modes,
index types, sparse accessors, scenes without a default, and malformed or
hostile inputs. Usage: python3 tools/make_test_gltf.py [OUTDIR]
"""
import json
import math
import os
import struct
import sys

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from gltf_writer import Gltf, UBYTE, USHORT, UINT, FLOAT, POINTS, LINES, TRIANGLE_STRIP  # noqa: E402

TRI = [(0, 0, 0), (1, 0, 0), (0, 1, 0)]


def transforms():
    """One triangle instanced by nodes with TRS, a child, a matrix and a mirror."""
    g = Gltf()
    mat = g.material("concrete")
    tri = g.mesh("tri", [g.primitive(TRI, [(0, 1, 2)], mat)])
    s = math.sqrt(0.5)
    child = g.node(name="child", mesh=tri, rotation=[0, 0, s, s], scale=[2, 2, 2])
    parent = g.node(name="parent", mesh=tri, translation=[10, 0, 0], children=[child])
    matrix = g.node(name="matrix", mesh=tri,
                    matrix=[3, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0, 0, 0, 5, 1])  # column-major: scale x 3, move z 5
    mirror = g.node(name="mirror", mesh=tri, scale=[-1, 1, 1])
    other = g.node(name="other_scene", mesh=tri, translation=[100, 0, 0])
    g.scene([parent, matrix, mirror], default=True)
    g.scene([other], default=False)
    return g


def mapping():
    """Six one-triangle primitives, each testing one mapping rule."""
    g = Gltf()
    prims = [
        g.primitive(TRI, None, g.material("wall_a", acoustic="glass_window")),  # map beats extras
        g.primitive(TRI, None, g.material("concrete", acoustic="carpet_thick")),  # extras beat name
        g.primitive(TRI, None, g.material("marble")),  # own name
        g.primitive(TRI, None, g.material("mystery")),  # nothing: default + warning
        g.primitive(TRI, None, None),  # no material: default + warning
        g.primitive(TRI, None, g.material("typo_target")),  # map names unknown material: warning, default
    ]
    g.scene([g.node(mesh=g.mesh("mapped", prims))])
    return g


def modes():
    """Index types u8/u16/u32, a non-indexed primitive, and three skipped modes."""
    g = Gltf()
    quad = [(0, 0, 0), (1, 0, 0), (1, 1, 0), (0, 1, 0)]
    m = g.material("concrete")
    prims = [
        g.primitive(TRI, [0, 1, 2], m, ctype=UBYTE),  # 1 triangle
        g.primitive(quad, [0, 1, 2, 0, 2, 3], m, ctype=USHORT),  # 2
        g.primitive(TRI, [0, 1, 2], m, ctype=UINT),  # 1
        g.primitive(TRI + [(0, 0, 1), (1, 0, 1), (0, 1, 1)], None, m),  # 2, non-indexed
        g.primitive(quad, [0, 1, 1, 2], m, mode=LINES),  # skipped
        g.primitive(quad, None, m, mode=POINTS),  # skipped
        g.primitive(quad, [0, 1, 3, 2], m, mode=TRIANGLE_STRIP),  # skipped
    ]
    g.scene([g.node(mesh=g.mesh("mixed", prims))])
    return g


def sparse():
    """Positions accessor whose vertex 2 is replaced by a sparse entry (0, 5, 0)."""
    g = Gltf()
    prim = g.primitive(TRI, [0, 1, 2], g.material("concrete"))
    acc = g.doc["accessors"][prim["attributes"]["POSITION"]]
    iv = g.view(struct.pack("<H", 2))
    vv = g.view(struct.pack("<3f", 0, 5, 0))
    acc["sparse"] = {"count": 1, "indices": {"bufferView": iv, "componentType": USHORT},
                     "values": {"bufferView": vv}}
    acc["max"] = [1, 5, 0]
    g.scene([g.node(mesh=g.mesh("sparse_tri", [prim]))])
    return g


def normalized():
    """Positions as normalized u16 (stride 8, as vertex attributes must be
    4-byte aligned): 65535 -> 1.0; the node scales by 2."""
    g = Gltf()
    data = b"".join(struct.pack("<4H", *p, 0) for p in [(0, 0, 0), (65535, 0, 0), (0, 65535, 0)])
    v = g.view(data, 34962)
    g.doc["bufferViews"][v]["byteStride"] = 8
    pos = g.accessor(bufferView=v, componentType=USHORT, normalized=True, count=3, type="VEC3",
                     min=[0, 0, 0], max=[65535, 65535, 0])
    prim = {"attributes": {"POSITION": pos}, "indices": g.indices([0, 1, 2], UBYTE), "material": g.material("concrete")}
    g.scene([g.node(mesh=g.mesh("quantized", [prim]), scale=[2, 2, 2])])
    return g


def no_scene():
    """No scenes at all: every root node (0 with child 1, and 2) is loaded."""
    g = Gltf()
    tri = g.mesh("tri", [g.primitive(TRI, [(0, 1, 2)], g.material("concrete"))])
    child = g.node(mesh=tri, translation=[0, 0, 1])
    g.node(mesh=tri, children=[child])
    g.node(mesh=tri, translation=[0, 0, 2])
    # Reorder so the child (index 0) precedes its parent: roots are 1 and 2.
    return g


def one_tri(name="bad_mesh", points=TRI):
    g = Gltf()
    g.scene([g.node(mesh=g.mesh(name, [g.primitive(points, [0, 1, 2], g.material("concrete"))]))])
    return g


def main():
    here = os.path.dirname(os.path.abspath(__file__))
    out = sys.argv[1] if len(sys.argv) > 1 else os.path.join(here, "..", "tests", "data", "gltf")
    os.makedirs(out, exist_ok=True)
    p = lambda n: os.path.join(out, n)  # noqa: E731

    transforms().write_gltf(p("transforms.gltf"))
    transforms().write_glb(p("transforms.glb"))
    mapping().write_gltf(p("mapping.gltf"))
    modes().write_gltf(p("modes.gltf"))
    sparse().write_gltf(p("sparse.gltf"))
    normalized().write_gltf(p("normalized.gltf"))
    g = no_scene()
    g.doc["scenes"] = []
    g.doc.pop("scene", None)
    g.write_gltf(p("no_scene.gltf"))

    one_tri(points=[(0, 0, 0), (float("nan"), 0, 0), (0, 1, 0)]).write_gltf(p("nan_vertex.gltf"))

    # Hostile counts and ranges: edit a valid document.
    for name, edit in [
        ("huge_count.gltf", lambda d: d["accessors"][0].update(count=10 ** 12)),
        ("view_outside_buffer.gltf", lambda d: d["bufferViews"][0].update(byteOffset=1000)),
        ("accessor_outside_view.gltf", lambda d: d["accessors"][0].update(byteOffset=8)),
        ("node_cycle.gltf", lambda d: d["nodes"].append({"children": [0]}) or d["nodes"][0].update(children=[1])),
        ("buffer_length_lie.gltf", lambda d: d["buffers"][0].update(byteLength=10 ** 12)),
        ("bad_material_index.gltf", lambda d: d["meshes"][0]["primitives"][0].update(material=7)),
    ]:
        d = json.loads(one_tri().gltf_text())
        edit(d)
        with open(p(name), "w", encoding="utf-8") as f:
            f.write(json.dumps(d, separators=(",", ":")) + "\n")
    # index_out_of_range: the u32 index buffer holds 0, 1, 9 (only 3 vertices).
    g = one_tri()
    idx_view = g.doc["accessors"][1]["bufferView"]
    off = g.doc["bufferViews"][idx_view]["byteOffset"]
    g.buf[off:off + 12] = struct.pack("<3I", 0, 1, 9)
    g.write_gltf(p("index_out_of_range.gltf"))

    with open(p("malformed.gltf"), "w", encoding="utf-8") as f:
        f.write('{"asset": {"version": "2.0"}, "meshes": [\n')
    with open(p("truncated.glb"), "wb") as f:
        f.write(struct.pack("<III", 0x46546C67, 2, 4096) + b"\x10\x00")
    print("wrote test glTF files to", out)


if __name__ == "__main__":
    main()
