#!/usr/bin/env python3
"""Hostile input, end to end (issue 17): makes a corpus of hostile files and
runs `earshot` on each, as a user would, under the limits the issue names.

Every case must end within 20 s (60 s in sanitizer builds) under a 2 GiB
address-space limit (not in sanitizer builds: they reserve terabytes of
address space up front) with either
  - exit 2 and exactly one "earshot: error: ..." line (a clean refusal), or
  - exit 0 and a documented warning on stderr (valid input that is probably
    not meant),
and in every case with every input file unchanged (hashed before and after)
and no byte of the secret file outside the case's folder in stdout, stderr or
any file the command wrote.

The corpus is generated (hostile files are easier to read as the code that
makes them, and the big ones would be megabytes): `--keep DIR` leaves it
there to look at or to fuzz from.

Usage: hostile_corpus.py --earshot PATH --source DIR [--sanitized] [--keep DIR] [-k NAME]
"""
import argparse
import base64
import hashlib
import json
import os
import resource
import shutil
import struct
import subprocess
import sys
import tempfile
import time
import wave

SECRET = b"root:x:0:0:EARSHOT-SECRET-7f3a9c:/root:/bin/bash\n"
MARKERS = [b"EARSHOT-SECRET-7f3a9c", b"7f3a9c"]

# ------------------------------------------------------------------ makers

TRI = struct.pack("<9f", 0, 0, 0, 1, 0, 0, 0, 1, 0)


def gltf(nodes, scenes=None, meshes=None, accessors=None, buffer_views=None, buffers=None, extra=None):
    """A glTF document; by default one triangle mesh in an embedded buffer."""
    doc = {
        "asset": {"version": "2.0"},
        "buffers": buffers if buffers is not None else [
            {"byteLength": len(TRI), "uri": "data:application/octet-stream;base64," + base64.b64encode(TRI).decode()}],
        "bufferViews": buffer_views if buffer_views is not None else [{"buffer": 0, "byteOffset": 0, "byteLength": 36}],
        "accessors": accessors if accessors is not None else [
            {"bufferView": 0, "componentType": 5126, "count": 3, "type": "VEC3"}],
        "meshes": meshes if meshes is not None else [{"name": "m", "primitives": [{"attributes": {"POSITION": 0}}]}],
        "nodes": nodes,
        "scenes": scenes if scenes is not None else [{"nodes": [0]}],
        "scene": 0,
    }
    if extra:
        doc.update(extra)
    return json.dumps(doc)


def box_gltf(lo=(0, 0, 0), hi=(10, 7, 3)):
    """A closed box (12 triangles, shared vertices) as glTF text."""
    x0, y0, z0 = lo
    x1, y1, z1 = hi
    v = [(x0, y0, z0), (x1, y0, z0), (x1, y1, z0), (x0, y1, z0), (x0, y0, z1), (x1, y0, z1), (x1, y1, z1), (x0, y1, z1)]
    f = [(0, 2, 1), (0, 3, 2), (4, 5, 6), (4, 6, 7), (0, 1, 5), (0, 5, 4), (1, 2, 6), (1, 6, 5), (2, 3, 7), (2, 7, 6),
         (3, 0, 4), (3, 4, 7)]
    data = b"".join(struct.pack("<3f", *p) for p in v) + b"".join(struct.pack("<3H", *t) for t in f)
    uri = "data:application/octet-stream;base64," + base64.b64encode(data).decode()
    return gltf(nodes=[{"mesh": 0}],
                buffers=[{"byteLength": len(data), "uri": uri}],
                buffer_views=[{"buffer": 0, "byteOffset": 0, "byteLength": 96},
                              {"buffer": 0, "byteOffset": 96, "byteLength": 72}],
                accessors=[{"bufferView": 0, "componentType": 5126, "count": 8, "type": "VEC3"},
                           {"bufferView": 1, "componentType": 5123, "count": 36, "type": "SCALAR"}],
                meshes=[{"name": "box", "primitives": [{"attributes": {"POSITION": 0}, "indices": 1}]}])


def wav_bytes(rate, frames, channels=1):
    import io
    b = io.BytesIO()
    with wave.open(b, "wb") as w:
        w.setnchannels(channels)
        w.setsampwidth(2)
        w.setframerate(rate)
        w.writeframes(b"\x01\x00" * frames * channels)
    return b.getvalue()


def crc8(data):
    c = 0
    for byte in data:
        c ^= byte
        for _ in range(8):
            c = ((c << 1) ^ 0x07) & 0xFF if c & 0x80 else (c << 1) & 0xFF
    return c


def crc16(data):
    c = 0
    for byte in data:
        c ^= byte << 8
        for _ in range(8):
            c = ((c << 1) ^ 0x8005) & 0xFFFF if c & 0x8000 else (c << 1) & 0xFFFF
    return c


def utf8_number(n):
    if n < 0x80:
        return bytes([n])
    if n < 0x800:
        return bytes([0xC0 | (n >> 6), 0x80 | (n & 0x3F)])
    if n < 0x10000:
        return bytes([0xE0 | (n >> 12), 0x80 | ((n >> 6) & 0x3F), 0x80 | (n & 0x3F)])
    return bytes([0xF0 | (n >> 18), 0x80 | ((n >> 12) & 0x3F), 0x80 | ((n >> 6) & 0x3F), 0x80 | (n & 0x3F)])


def flac_of_silence(frames_of_4096):
    """An honest FLAC stream of silence (CONSTANT subframes, ~10 bytes per
    4096 samples) whose STREAMINFO leaves the length unknown (0): only the
    decoder's output can tell how big it is. 8192 frames: 33.5 M samples in
    ~90 KB."""
    info = struct.pack(">HH", 4096, 4096) + b"\x00" * 6
    packed = (48000 << 44) | (0 << 41) | (15 << 36) | 0  # rate, channels-1, bps-1, total samples unknown
    info += packed.to_bytes(8, "big") + b"\x00" * 16
    out = bytearray(b"fLaC" + bytes([0x80, 0, 0, 34]) + info)
    for n in range(frames_of_4096):
        header = bytes([0xFF, 0xF8, 0xCA, 0x08]) + utf8_number(n)  # 4096 samples, 48 kHz, mono, 16 bit
        header += bytes([crc8(header)])
        frame = header + b"\x00\x00\x00"  # CONSTANT subframe, value 0
        out += frame + crc16(frame).to_bytes(2, "big")
    return bytes(out)


def scene_json(listener=(7, 3.5, 1.5), sources=None, settings=None, extra=None):
    doc = {
        "geometry": "room.gltf",
        "listener": {"position": list(listener), "forward": [-1, 0, 0], "up": [0, 0, 1]},
        "sources": sources if sources is not None else [{"name": "a", "audio": "dry.wav", "position": [2, 3.5, 1.5]}],
        "settings": settings if settings is not None else {"quality": "draft", "duration": 0.5},
    }
    if extra:
        doc.update(extra)
    return json.dumps(doc)


# ------------------------------------------------------------------ cases

class Case:
    def __init__(self, name, files, args, expect, contains=None, outputs=(), setup=None, stdout_lacks=None):
        self.name = name
        self.files = files        # name -> bytes or str (written into the case folder)
        self.args = args          # earshot arguments, {dir} and {outside} substituted
        self.expect = expect      # "error" or "warning"
        self.contains = contains  # a text the error/warning must contain
        self.outputs = outputs    # files the command may write (not inputs)
        self.setup = setup        # callable(dir) for links, FIFOs
        self.stdout_lacks = stdout_lacks


def cases(src):
    room = box_gltf()
    dry = wav_bytes(48000, 4800)
    base_ir = ["ir", "{dir}/room.gltf", "--source", "2,3.5,1.5", "--listener", "7,3.5,1.5", "--receiver", "omni",
               "--quality", "draft", "-o", "{dir}/ir.wav"]
    binaural = ["ir", "{dir}/room.gltf", "--source", "2,3.5,1.5", "--listener", "7,3.5,1.5", "--quality", "draft"]
    scene_files = {"room.gltf": room, "dry.wav": dry}
    c = []

    # 1. Confinement: references never leave the referring file's folder; no
    #    byte of the file they name appears anywhere.
    for uri in ["../secret.bin", "%2e%2e/secret.bin", "{outside}/secret.bin", "sub/../../secret.bin", "link.bin"]:
        def mk(d, uri=uri):
            if uri == "link.bin":
                os.symlink(os.path.join(os.path.dirname(d), "secret.bin"), os.path.join(d, "link.bin"))
        c.append(Case("gltf buffer uri " + uri, {"room.gltf": gltf(
            nodes=[{"mesh": 0}], buffers=[{"byteLength": len(SECRET), "uri": uri}])},
            ["ir", "{dir}/room.gltf", "--source", "0.2,0.2,1", "--listener", "0.5,0.5,1", "-o", "{dir}/ir.wav"],
            "error", outputs=["ir.wav"], setup=mk))
    c.append(Case("gltf image uri outside", {"room.gltf": gltf(nodes=[{"mesh": 0}], extra={
        "images": [{"uri": "../secret.bin"}]})}, base_ir, "warning", contains="leads outside", outputs=["ir.wav"]))
    for field, value in [("geometry", "../secret.bin"), ("materials", "{outside}/secret.bin"),
                         ("material_map", "../secret.bin")]:
        c.append(Case("scene " + field + " outside", dict(scene_files, **{"scene.json": json.loads(
            scene_json()) | {field: value}}), ["render", "{dir}/scene.json", "-o", "{dir}/out.wav", "--quiet"],
            "error", contains=field, outputs=["out.wav"]))
    c.append(Case("scene audio via symlink out", dict(scene_files, **{"scene.json": scene_json(
        sources=[{"name": "a", "audio": "link.wav", "position": [2, 3.5, 1.5]}])}),
        ["render", "{dir}/scene.json", "-o", "{dir}/out.wav", "--quiet"], "error", contains="leads outside",
        outputs=["out.wav"], setup=lambda d: os.symlink(os.path.join(os.path.dirname(d), "secret.bin"),
                                                        os.path.join(d, "link.wav"))))
    c.append(Case("scene hrtf absolute", dict(scene_files, **{"scene.json": scene_json(
        settings={"hrtf": "/etc/hostname", "duration": 0.5})}),
        ["render", "{dir}/scene.json", "-o", "{dir}/out.wav", "--quiet"], "error", contains="settings.hrtf",
        outputs=["out.wav"]))
    # Named on the command line (allowed), but its bytes never echoed.
    for opt in ["--material-map", "--materials"]:
        c.append(Case("secret as " + opt, {"room.gltf": room}, base_ir + [opt, "{outside}/secret.bin"], "error",
                      outputs=["ir.wav"]))
    c.append(Case("secret as tolerance", {"a.wav": dry}, ["compare", "{dir}/a.wav", "{dir}/a.wav", "--tolerance",
                                                           "{outside}/secret.bin"], "error"))

    # Names from a file are escaped: one that holds a newline and a forged
    # error line gives one error line, not two.
    forged = "x\nearshot: error: FORGED\x1b[2J"
    c.append(Case("material map key forges a line", {"room.gltf": room, "map.json": json.dumps({forged: 5})},
                  base_ir + ["--material-map", "{dir}/map.json"], "error", contains="x\\nearshot", outputs=["ir.wav"]))
    c.append(Case("materials key forges a line", {"room.gltf": room, "m.json": json.dumps(
        {"bands_hz": [1000], "materials": {"default": {"absorption": [0.1], forged: 1}}})},
        base_ir + ["--materials", "{dir}/m.json"], "error", contains="x\\nearshot", outputs=["ir.wav"]))
    c.append(Case("tolerance key forges a line", {"a.wav": dry, "t.json": json.dumps({forged: 1})},
                  ["compare", "{dir}/a.wav", "{dir}/a.wav", "--tolerance", "{dir}/t.json"], "error",
                  contains="x\\nearshot"))

    # 2. Memory errors and hangs in SOFA reading.
    for sofa in ["not_sofa.sofa", "pulse_truncated.sofa"]:
        c.append(Case("sofa " + sofa, {"room.gltf": room, "h.sofa": open(os.path.join(
            src, "tests/fuzz/corpus/sofa", sofa), "rb").read()},
            binaural + ["--hrtf", "{dir}/h.sofa", "-o", "{dir}/ir.wav"], "error", contains="SOFA", outputs=["ir.wav"]))
    c.append(Case("sofa is hdf5 junk", {"room.gltf": room, "h.sofa": b"\x89HDF\r\n\x1a\n" + b"\xff" * 4000},
                  binaural + ["--hrtf", "{dir}/h.sofa", "-o", "{dir}/ir.wav"], "error", contains="SOFA",
                  outputs=["ir.wav"]))

    # 3. No abort: coordinates Embree cannot take.
    c.append(Case("gltf translation 1e19", {"room.gltf": gltf(nodes=[{"mesh": 0, "translation": [1e19, 0, 0]}])},
                  base_ir, "error", contains="farther than", outputs=["ir.wav"]))
    big = struct.pack("<9f", 0, 0, 0, 1.8e19, 0, 0, 0, 1, 0)
    c.append(Case("gltf vertex 1.8e19", {"room.gltf": gltf(nodes=[{"mesh": 0}], buffers=[
        {"byteLength": 36, "uri": "data:application/octet-stream;base64," + base64.b64encode(big).decode()}])},
        base_ir, "error", contains="farther than", outputs=["ir.wav"]))
    c.append(Case("gltf scale 1e300", {"room.gltf": gltf(nodes=[{"mesh": 0, "scale": [1e300, 1, 1]}])},
                  base_ir, "error", outputs=["ir.wav"]))
    c.append(Case("cli source 1e19", {"room.gltf": room},
                  ["ir", "{dir}/room.gltf", "--source", "1e19,0,0", "--listener", "7,3.5,1.5", "-o", "{dir}/ir.wav"],
                  "error", contains="1e6 m", outputs=["ir.wav"]))
    c.append(Case("scene listener 1e19", dict(scene_files, **{"scene.json": scene_json(listener=(1e19, 0, 0))}),
                  ["render", "{dir}/scene.json", "-o", "{dir}/out.wav", "--quiet"], "error", outputs=["out.wav"]))

    # 4. No recursion on input depth.
    c.append(Case("gltf extras 30k deep", {"room.gltf": gltf(nodes=[{"mesh": 0}]).replace(
        '"scene": 0', '"scene": 0, "extras": ' + "[" * 30000 + "]" * 30000)}, base_ir, "error", contains="nested",
        outputs=["ir.wav"]))
    c.append(Case("materials 300k deep", {"room.gltf": room, "m.json": '{"bands_hz": ' + "[" * 300000 + "]" * 300000 + "}"},
                  base_ir + ["--materials", "{dir}/m.json"], "error", contains="nested", outputs=["ir.wav"]))
    c.append(Case("material map 100k deep", {"room.gltf": room, "map.json": '{"a": ' + "{" * 100000 + "}" * 100000 + "}"},
                  base_ir + ["--material-map", "{dir}/map.json"], "error", contains="nested", outputs=["ir.wav"]))
    c.append(Case("scene 200k deep", dict(scene_files, **{"scene.json": '{"description": ' + "[" * 200000 + "]" * 200000 + "}"}),
                  ["render", "{dir}/scene.json", "-o", "{dir}/out.wav", "--quiet"], "error", outputs=["out.wav"]))
    c.append(Case("tolerance 100k deep", {"a.wav": dry, "t.json": "[" * 100000 + "]" * 100000},
                  ["compare", "{dir}/a.wav", "{dir}/a.wav", "--tolerance", "{dir}/t.json"], "error", contains="nested"))

    # 5. Outputs never destroy inputs, FIFOs or devices.
    c.append(Case("ir -o onto materials", {"room.gltf": room, "m.json": open(
        os.path.join(src, "materials/default.json")).read()},
        base_ir[:-2] + ["--materials", "{dir}/m.json", "-o", "{dir}/m.json"], "error", contains="input"))
    c.append(Case("ir --json onto map", {"room.gltf": room, "map.json": '{"x": "concrete"}'},
                  base_ir + ["--material-map", "{dir}/map.json", "--json", "{dir}/map.json"], "error",
                  contains="input", outputs=["ir.wav"]))
    c.append(Case("ir -o onto hrtf", {"room.gltf": room, "h.sofa": open(
        os.path.join(src, "tests/fuzz/corpus/sofa/Pulse.sofa"), "rb").read()},
        binaural + ["--hrtf", "{dir}/h.sofa", "-o", "{dir}/h.sofa"], "error", contains="input"))
    c.append(Case("ir -o onto geometry", {"room.gltf": room}, base_ir[:-2] + ["-o", "{dir}/room.gltf"], "error"))
    c.append(Case("ir -o hard link to geometry", {"room.gltf": room}, base_ir[:-2] + ["-o", "{dir}/hard.gltf"],
                  "error", contains="input", setup=lambda d: os.link(os.path.join(d, "room.gltf"),
                                                                     os.path.join(d, "hard.gltf"))))
    c.append(Case("ir -o symlink to geometry", {"room.gltf": room}, base_ir[:-2] + ["-o", "{dir}/sym.gltf"],
                  "error", contains="input", setup=lambda d: os.symlink("room.gltf", os.path.join(d, "sym.gltf"))))
    c.append(Case("ir -o onto a FIFO", {"room.gltf": room}, base_ir[:-2] + ["-o", "{dir}/fifo"], "error",
                  contains="FIFO", setup=lambda d: os.mkfifo(os.path.join(d, "fifo"))))
    c.append(Case("ir -o onto /dev/null", {"room.gltf": room}, base_ir[:-2] + ["-o", "/dev/null"], "error",
                  contains="device"))
    c.append(Case("ir -o onto a directory", {"room.gltf": room}, base_ir[:-2] + ["-o", "{dir}/d"], "error",
                  setup=lambda d: os.mkdir(os.path.join(d, "d"))))
    for target in ["dry.wav", "scene.json", "room.gltf"]:
        c.append(Case("render -o onto " + target, dict(scene_files, **{"scene.json": scene_json()}),
                      ["render", "{dir}/scene.json", "-o", "{dir}/" + target, "--quiet"], "error", contains="input"))
    # One command's two outputs naming one file: the second would replace the
    # first (before, `ir -o x --json x` left only the JSON).
    c.append(Case("ir -o and --json one file", {"room.gltf": room}, base_ir + ["--json", "{dir}/ir.wav"], "error",
                  contains="same file"))
    c.append(Case("ir --json a hard link to -o", {"room.gltf": room, "old.wav": dry},
                  base_ir[:-2] + ["-o", "{dir}/old.wav", "--json", "{dir}/old.json"], "error", contains="same file",
                  setup=lambda d: os.link(os.path.join(d, "old.wav"), os.path.join(d, "old.json"))))
    c.append(Case("ir --json through a symlink to -o", {"room.gltf": room, "old.wav": dry},
                  base_ir[:-2] + ["-o", "{dir}/old.wav", "--json", "{dir}/sub/old.wav"], "error",
                  contains="same file", setup=lambda d: os.symlink(".", os.path.join(d, "sub"))))
    # An output that cannot be written is found before the first is written.
    c.append(Case("ir --json into a missing folder", {"room.gltf": room}, base_ir + ["--json", "{dir}/no/s.json"],
                  "error", contains="does not exist"))
    c.append(Case("ir --json under a file", {"room.gltf": room}, base_ir + ["--json", "{dir}/room.gltf/s.json"],
                  "error", contains="not a folder"))
    tradeoff = ["tradeoff", "{dir}/room.gltf", "--source", "2,3.5,1.5", "--listener", "7,3.5,1.5", "--rays", "100",
                "--bounces", "2", "--repeats", "1"]
    plot_script = open(os.path.join(src, "tools/plot_tradeoff.py")).read()
    c.append(Case("tradeoff -o and --plot one file", {"room.gltf": room, "p.py": plot_script}, tradeoff + [
        "-o", "{dir}/t.csv", "--plot", "{dir}/t.csv", "--plot-script", "{dir}/p.py"], "error", contains="same file"))
    c.append(Case("tradeoff --plot onto its plot script", {"room.gltf": room, "p.py": plot_script}, tradeoff + [
        "-o", "{dir}/t.csv", "--plot", "{dir}/p.py", "--plot-script", "{dir}/p.py"], "error", contains="input"))
    c.append(Case("render -o a hard link to its audio", dict(scene_files, **{"scene.json": scene_json()}),
                  ["render", "{dir}/scene.json", "-o", "{dir}/hard.wav", "--quiet"], "error", contains="input",
                  setup=lambda d: os.link(os.path.join(d, "dry.wav"), os.path.join(d, "hard.wav"))))
    c.append(Case("tradeoff -o onto materials", {"room.gltf": room, "m.json": open(
        os.path.join(src, "materials/default.json")).read()},
        ["tradeoff", "{dir}/room.gltf", "--materials", "{dir}/m.json", "--source", "2,3.5,1.5", "--listener",
         "7,3.5,1.5", "--rays", "100", "--bounces", "2", "--repeats", "1", "-o", "{dir}/m.json"], "error",
        contains="input"))

    # 6. Unbounded resources.
    n = 40  # node i lists node i + 1 twice: 2^40 placements of one mesh
    dag = [{"children": [i + 1, i + 1]} for i in range(n)] + [{"mesh": 0}]
    c.append(Case("gltf node DAG 2^40", {"room.gltf": gltf(nodes=dag)}, base_ir, "error", contains="over the",
                  outputs=["ir.wav"]))
    dag2 = [{"children": [i + 1, i + 1], "mesh": 0} for i in range(30)] + [{"mesh": 0}]
    c.append(Case("gltf node DAG with meshes at every level", {"room.gltf": gltf(nodes=dag2)}, base_ir, "error",
                  contains="over the", outputs=["ir.wav"]))
    many = 300000
    tris = struct.pack("<9f", 0, 0, 0, 1, 0, 0, 0, 1, 0) * 1000
    c.append(Case("gltf repeated scene roots", {"room.gltf": gltf(
        nodes=[{"mesh": 0}], scenes=[{"nodes": [0] * many}],
        buffers=[{"byteLength": len(tris), "uri": "data:application/octet-stream;base64," + base64.b64encode(tris).decode()}],
        buffer_views=[{"buffer": 0, "byteOffset": 0, "byteLength": len(tris)}],
        accessors=[{"bufferView": 0, "componentType": 5126, "count": 3000, "type": "VEC3"}])},
        base_ir, "error", contains="over the", outputs=["ir.wav"]))
    sparse = {"bufferView": None, "componentType": 5126, "count": 1 << 24, "type": "VEC3",
              "sparse": {"count": 1, "indices": {"bufferView": 1, "componentType": 5125},
                         "values": {"bufferView": 0}}}
    del sparse["bufferView"]
    idx = struct.pack("<I", 0) + b"\x00" * 8
    data = struct.pack("<3f", 0, 0, 0) + idx
    c.append(Case("gltf buffer-less sparse accessors x 64 nodes", {"room.gltf": gltf(
        nodes=[{"mesh": 0}] * 64, scenes=[{"nodes": list(range(64))}],
        buffers=[{"byteLength": len(data), "uri": "data:application/octet-stream;base64," + base64.b64encode(data).decode()}],
        buffer_views=[{"buffer": 0, "byteOffset": 0, "byteLength": 12}, {"buffer": 0, "byteOffset": 12, "byteLength": 4}],
        accessors=[sparse])}, base_ir, "error", contains="over the", outputs=["ir.wav"]))
    # A ray count or histogram whose trace would hold gigabytes (1e8 rays:
    # ~12 GiB; 0.01 ms bins over 60 s: ~5.5 GiB): refused before tracing;
    # likewise an IR whose synthesis would.
    c.append(Case("scene rays 1e8", dict(scene_files, **{"scene.json": scene_json(
        settings={"rays": 100000000, "duration": 0.5})}),
        ["render", "{dir}/scene.json", "-o", "{dir}/out.wav", "--quiet"], "error", contains="settings.rays",
        outputs=["out.wav"]))
    # 64 sources with binaural reflections: each slot may hold ~31 MB with
    # its IRs (10 s), 2 GB for all: refused before anything is loaded.
    many_sources = [{"name": "s%d" % i, "audio": "dry.wav", "position": [2, 1 + 0.05 * i, 1.5]} for i in range(64)]
    c.append(Case("scene 64 sources with binaural reflections", dict(scene_files, **{"scene.json": scene_json(
        sources=many_sources, settings={"quality": "draft", "duration": 0.5, "ambisonic_order": 0})}),
        ["render", "{dir}/scene.json", "-o", "{dir}/out.wav", "--quiet"], "error", contains="64 sources need about",
        outputs=["out.wav"]))
    c.append(Case("cli rays 1e8", {"room.gltf": room}, base_ir + ["--rays", "100000000"], "error",
                  contains="--max-memory", outputs=["ir.wav"]))
    c.append(Case("cli 0.01 ms bins over 60 s", {"room.gltf": room},
                  base_ir + ["--bin-ms", "0.01", "--length", "60"], "error", contains="--max-memory",
                  outputs=["ir.wav"]))
    # An IR whose synthesis would hold ~8 GiB (60 s at 384 kHz, 16 channels).
    c.append(Case("cli 60 s third-order IR at 384 kHz", {"room.gltf": room},
                  [a if a != "omni" else "ambisonic" for a in base_ir] + ["--order", "3", "--rate", "384000",
                                                                          "--length", "60"],
                  "error", contains="--max-memory", outputs=["ir.wav"]))
    c.append(Case("wav at 1 Hz resampled", dict(scene_files, **{"dry.wav": wav_bytes(1, 200000),
                                                                  "scene.json": scene_json()}),
                  ["render", "{dir}/scene.json", "-o", "{dir}/out.wav", "--quiet"], "error", contains="memory limit",
                  outputs=["out.wav"]))
    c.append(Case("flac of silence decoding to 33M samples", {"big.flac": flac_of_silence(8192)},
                  ["analyze", "{dir}/big.flac"], "error", contains="limit"))
    c.append(Case("flac of silence in compare", {"big.flac": flac_of_silence(8192), "a.wav": dry},
                  ["compare", "{dir}/a.wav", "{dir}/big.flac"], "error", contains="limit"))
    c.append(Case("render 86400 s", dict(scene_files, **{"scene.json": scene_json(
        settings={"quality": "draft", "duration": 86400})}),
        ["render", "{dir}/scene.json", "-o", "{dir}/out.wav", "--quiet"], "error", contains="WAV",
        outputs=["out.wav"]))
    # 4000 sources: their slots with the IRs they may hold (0.9 MB each with
    # the defaults' shared tail, nothing kept for sourceIr()) pass 1 GiB;
    # refused before anything is loaded. (1000 render within the limit:
    # 0.72 GB peak, their simulations in groups.)
    c.append(Case("render 4000 sources", dict(scene_files, **{"scene.json": scene_json(sources=[
        {"name": "s%d" % i, "audio": "dry.wav", "position": [2, 3.5, 1.5]} for i in range(4000)])}),
        ["render", "{dir}/scene.json", "-o", "{dir}/out.wav", "--quiet"], "error", contains="4000 sources need about",
        outputs=["out.wav"]))
    for what, args in [
        ("materials", base_ir + ["--materials", "/dev/zero"]),
        ("material map", base_ir + ["--material-map", "/dev/zero"]),
        ("geometry", ["ir", "/dev/zero", "--source", "1,1,1", "--listener", "2,2,2", "-o", "{dir}/ir.wav"]),
        ("hrtf", binaural + ["--hrtf", "/dev/zero", "-o", "{dir}/ir.wav"]),
        ("scene", ["render", "/dev/zero", "-o", "{dir}/out.wav"]),
        ("analyze input", ["analyze", "/dev/zero"]),
        ("tolerance", ["compare", "{dir}/a.wav", "{dir}/a.wav", "--tolerance", "/dev/zero"]),
    ]:
        c.append(Case("/dev/zero as " + what, {"room.gltf": room, "a.wav": dry}, args, "error",
                      contains="regular file", outputs=["ir.wav", "out.wav"]))
    for what, args in [
        ("materials", base_ir + ["--materials", "{dir}/fifo"]),
        ("geometry", ["ir", "{dir}/fifo", "--source", "1,1,1", "--listener", "2,2,2", "-o", "{dir}/ir.wav"]),
        ("scene audio", ["render", "{dir}/scene.json", "-o", "{dir}/out.wav", "--quiet"]),
        ("compare reference", ["compare", "{dir}/a.wav", "{dir}/fifo"]),
    ]:
        files = {"room.gltf": room, "a.wav": dry, "scene.json": scene_json(
            sources=[{"name": "a", "audio": "fifo", "position": [2, 3.5, 1.5]}])}
        c.append(Case("FIFO as " + what, files, args, "error", contains="FIFO", outputs=["ir.wav", "out.wav"],
                      setup=lambda d: os.mkfifo(os.path.join(d, "fifo"))))

    # 8. Silent nonsense: a warning where it can be valid, an error where not.
    c.append(Case("gltf with 0 triangles", {"room.gltf": gltf(nodes=[{}])}, base_ir, "warning",
                  contains="no triangles", outputs=["ir.wav"]))
    orphan = {"name": "orphan", "primitives": [{"attributes": {"POSITION": 0}}]}
    c.append(Case("mesh no node places", {"room.gltf": gltf(nodes=[{"mesh": 0}], meshes=[
        {"name": "m", "primitives": [{"attributes": {"POSITION": 0}}]}, orphan])},
        base_ir, "warning", contains="not placed", outputs=["ir.wav"]))
    c.append(Case("listener outside the closed room", {"room.gltf": room},
                  ["ir", "{dir}/room.gltf", "--source", "2,3.5,1.5", "--listener", "17,3.5,1.5", "--receiver", "omni",
                   "--quality", "draft", "-o", "{dir}/ir.wav"], "warning", contains="outside the closed volume",
                  outputs=["ir.wav"]))
    c.append(Case("compare window of 1 ns", {"a.wav": dry}, ["compare", "{dir}/a.wav", "{dir}/a.wav", "--window",
                                                             "0,1e-9"], "error", contains="shorter than one sample"))
    c.append(Case("compare window of 30 ms: no ratio", {"a.wav": dry, "t.json": '{"metrics": {"Ts": false}}'}, ["compare", "{dir}/a.wav", "{dir}/a.wav",
                                                                       "--window", "0,0.03", "--tolerance", "{dir}/t.json"],
                  "error", contains="no metric"))
    c.append(Case("scene update rate 1e-300", dict(scene_files, **{"scene.json": scene_json(
        settings={"update_rate_hz": 1e-300, "duration": 0.5})}),
        ["render", "{dir}/scene.json", "-o", "{dir}/out.wav", "--quiet"], "error", contains="update_rate_hz",
        outputs=["out.wav"]))
    c.append(Case("cli seed -1", {"room.gltf": room}, base_ir + ["--seed", "-1"], "error", contains="--seed",
                  outputs=["ir.wav"]))
    c.append(Case("scene seed -1", dict(scene_files, **{"scene.json": scene_json(
        settings={"seed": -1, "duration": 0.5})}), ["render", "{dir}/scene.json", "-o", "{dir}/out.wav", "--quiet"],
        "error", contains="seed", outputs=["out.wav"]))
    c.append(Case("--max-memory garbage", {"room.gltf": room}, base_ir + ["--max-memory", "lots"], "error",
                  contains="max-memory", outputs=["ir.wav"]))
    return c


# ------------------------------------------------------------------ runner

def snapshot(folder):
    out = {}
    for root, _, files in os.walk(folder):
        for f in files:
            p = os.path.join(root, f)
            if os.path.islink(p) or not os.path.isfile(p):
                continue
            with open(p, "rb") as fh:
                out[os.path.relpath(p, folder)] = hashlib.sha256(fh.read()).hexdigest()
    return out


def limit_address_space():
    resource.setrlimit(resource.RLIMIT_AS, (2 << 30, 2 << 30))


def run_case(case, earshot, work, sanitized):
    case_dir = os.path.join(work, "case")
    os.makedirs(case_dir)
    for name, content in case.files.items():
        if isinstance(content, dict):
            content = json.dumps(content)
        if isinstance(content, str):
            content = content.replace("{outside}", work)
        with open(os.path.join(case_dir, name), "wb") as f:
            f.write(content.encode() if isinstance(content, str) else content)
    if case.setup:
        case.setup(case_dir)
    args = [a.replace("{dir}", case_dir).replace("{outside}", work) for a in case.args]
    before = snapshot(work)
    limit = 60 if sanitized else 20
    t0 = time.monotonic()
    try:
        p = subprocess.run([earshot] + args, capture_output=True, timeout=limit, stdin=subprocess.DEVNULL,
                           preexec_fn=None if sanitized else limit_address_space)
    except subprocess.TimeoutExpired:
        return ["did not finish within %d s" % limit]
    seconds = time.monotonic() - t0
    problems = []
    stderr = p.stderr.decode(errors="replace")
    errors = [l for l in stderr.splitlines() if l.startswith("earshot: error:")]
    warnings = [l for l in stderr.splitlines() if "warning:" in l]
    if case.expect == "error":
        if p.returncode != 2:
            problems.append("exit %d, expected 2" % p.returncode)
        if len(errors) != 1:
            problems.append("%d error lines, expected 1" % len(errors))
        elif len(errors[0]) > 600:
            problems.append("error line of %d characters" % len(errors[0]))
        text = errors[0] if errors else ""
    else:
        if p.returncode != 0:
            problems.append("exit %d, expected 0 with a warning" % p.returncode)
        text = "\n".join(warnings)
        if not warnings:
            problems.append("no warning")
    if case.contains and case.contains not in text:
        problems.append("message lacks %r" % case.contains)
    after = snapshot(work)
    for f, h in before.items():
        if after.get(f) != h:
            problems.append("input %s changed or vanished" % f)
    written = [f for f in after if f not in before]
    for f in written:
        if os.path.basename(f) not in case.outputs:
            problems.append("wrote %s" % f)
    blobs = [p.stdout, p.stderr] + [open(os.path.join(work, f), "rb").read() for f in written]
    if any(m in b for b in blobs for m in MARKERS):
        problems.append("a byte of the secret file outside the folder reached an output")
    if problems:
        problems.append("stderr: " + stderr.strip()[:800])
    return problems, seconds, (errors[0] if case.expect == "error" and errors else text)[:160]


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--earshot", required=True)
    ap.add_argument("--source", required=True)
    ap.add_argument("--sanitized", action="store_true")
    ap.add_argument("--keep")
    ap.add_argument("-k", help="only cases whose name contains this")
    a = ap.parse_args()
    passed = failed = 0
    for case in cases(a.source):
        if a.k and a.k not in case.name:
            continue
        work = tempfile.mkdtemp(prefix="earshot_hostile_")
        with open(os.path.join(work, "secret.bin"), "wb") as f:
            f.write(SECRET)
        try:
            result = run_case(case, a.earshot, work, a.sanitized)
            if isinstance(result, list):
                problems, seconds, said = result, None, ""
            else:
                problems, seconds, said = result
            status = "ok  " if not problems else "FAIL"
            print("%s %-48s %6s  %s" % (status, case.name, "%.2fs" % seconds if seconds is not None else "-", said))
            for pr in problems:
                print("       " + pr)
            passed += not problems
            failed += bool(problems)
        finally:
            if a.keep:
                shutil.copytree(work, os.path.join(a.keep, case.name.replace("/", "_").replace(" ", "_")), symlinks=True,
                                ignore=lambda d, names: [n for n in names if n == "fifo"])
            shutil.rmtree(work, ignore_errors=True)
    print("%d passed, %d failed" % (passed, failed))
    return 1 if failed else 0


if __name__ == "__main__":
    sys.exit(main())
