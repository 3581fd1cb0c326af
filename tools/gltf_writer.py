"""Minimal glTF 2.0 writer (.gltf with a base64-embedded buffer, or .glb) for
earshot's generated test files and sample scenes. Pure Python 3, no
dependencies. Positions are float32 VEC3; indices u8/u16/u32.
"""
import base64
import json
import struct

BYTE, UBYTE, SHORT, USHORT, UINT, FLOAT = 5120, 5121, 5122, 5123, 5125, 5126
POINTS, LINES, LINE_LOOP, LINE_STRIP, TRIANGLES, TRIANGLE_STRIP, TRIANGLE_FAN = range(7)
_FMT = {UBYTE: "B", USHORT: "H", UINT: "I", FLOAT: "f", BYTE: "b", SHORT: "h"}


class Gltf:
    def __init__(self):
        self.buf = bytearray()
        self.doc = {"asset": {"version": "2.0", "generator": "earshot tools/gltf_writer.py"},
                    "buffers": [], "bufferViews": [], "accessors": [], "meshes": [], "nodes": [],
                    "materials": [], "scenes": []}
        self._materials = {}

    # -- raw building blocks ------------------------------------------------
    def view(self, data, target=None):
        while len(self.buf) % 4:
            self.buf.append(0)
        v = {"buffer": 0, "byteOffset": len(self.buf), "byteLength": len(data)}
        if target:
            v["target"] = target
        self.buf += data
        self.doc["bufferViews"].append(v)
        return len(self.doc["bufferViews"]) - 1

    def accessor(self, **fields):
        self.doc["accessors"].append(fields)
        return len(self.doc["accessors"]) - 1

    def positions(self, points):
        data = b"".join(struct.pack("<3f", *map(float, p)) for p in points)
        v = self.view(data, 34962)
        finite = [p for p in points if all(c == c and abs(c) != float("inf") for c in p)] or [(0, 0, 0)]
        lo = [min(float(p[i]) for p in finite) for i in range(3)]
        hi = [max(float(p[i]) for p in finite) for i in range(3)]
        return self.accessor(bufferView=v, componentType=FLOAT, count=len(points), type="VEC3", min=lo, max=hi)

    def indices(self, idx, ctype=UINT):
        data = struct.pack("<%d%s" % (len(idx), _FMT[ctype]), *idx)
        v = self.view(data, 34963)
        return self.accessor(bufferView=v, componentType=ctype, count=len(idx), type="SCALAR")

    def material(self, name, acoustic=None, color=(0.8, 0.8, 0.8)):
        key = (name, acoustic)
        if key in self._materials:
            return self._materials[key]
        m = {"name": name, "pbrMetallicRoughness": {"baseColorFactor": list(color) + [1.0]}}
        if acoustic:
            m["extras"] = {"acoustic_material": acoustic}
        self.doc["materials"].append(m)
        self._materials[key] = len(self.doc["materials"]) - 1
        return self._materials[key]

    def primitive(self, points, tris=None, material=None, mode=None, ctype=UINT):
        """A primitive dict; tris is a flat index list or a list of triples."""
        p = {"attributes": {"POSITION": self.positions(points)}}
        if tris is not None:
            flat = [i for t in tris for i in (t if isinstance(t, (list, tuple)) else [t])]
            p["indices"] = self.indices(flat, ctype)
        if material is not None:
            p["material"] = material
        if mode is not None:
            p["mode"] = mode
        return p

    def mesh(self, name, primitives):
        self.doc["meshes"].append({"name": name, "primitives": primitives})
        return len(self.doc["meshes"]) - 1

    def node(self, **fields):
        self.doc["nodes"].append(fields)
        return len(self.doc["nodes"]) - 1

    def scene(self, nodes, default=True):
        self.doc["scenes"].append({"nodes": nodes})
        if default:
            self.doc["scene"] = len(self.doc["scenes"]) - 1

    # -- output ----------------------------------------------------------------
    def _finish(self, uri):
        doc = {k: v for k, v in self.doc.items() if v != []}
        buffer = {"byteLength": len(self.buf)}
        if uri:
            buffer["uri"] = "data:application/octet-stream;base64," + base64.b64encode(bytes(self.buf)).decode()
        doc["buffers"] = [buffer]
        return doc

    def gltf_text(self):
        return json.dumps(self._finish(True), separators=(",", ":")) + "\n"

    def write_gltf(self, path):
        with open(path, "w", encoding="utf-8") as f:
            f.write(self.gltf_text())

    def write_glb(self, path):
        js = json.dumps(self._finish(False), separators=(",", ":")).encode()
        js += b" " * (-len(js) % 4)
        binary = bytes(self.buf) + b"\0" * (-len(self.buf) % 4)
        total = 12 + 8 + len(js) + 8 + len(binary)
        with open(path, "wb") as f:
            f.write(struct.pack("<III", 0x46546C67, 2, total))
            f.write(struct.pack("<II", len(js), 0x4E4F534A) + js)
            f.write(struct.pack("<II", len(binary), 0x004E4942) + binary)
