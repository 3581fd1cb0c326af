#!/usr/bin/env python3
"""Writes the seed programs of fuzz_capi (tests/fuzz/corpus/capi/*.bin).

Each byte means what fuzz_capi.cpp's Program reads at that point; the
helpers below mirror its readers. Run from anywhere:
    python3 tests/fuzz/make_capi_seeds.py
"""
import os
import struct

OUT = os.path.join(os.path.dirname(os.path.abspath(__file__)), "corpus", "capi")

(SCENE_CREATE, SCENE_RELEASE, ADD_MATERIAL, MESH_CREATE, MESH_RELEASE, ADD_OR_REMOVE_MESH, _ADD2, COMMIT,
 SET_SCENE, TRANSFORM, SET_MATERIAL, SOURCE_CREATE, SOURCE_RELEASE, SOURCE_MOVE, SOURCE_SETTINGS, LISTENER,
 SIMULATE, PROCESS, _PROCESS2, GET_IR, COMPUTE_IR, FIND_MESH, LOAD_GLTF, INFO, NEW_CONTEXT, MEMORY_LIMIT,
 SIMULATION_THREAD) = range(27)

NAN = float("nan")


def f(v):
    """A raw float (selector >= 128, then its four bytes)."""
    return bytes([200]) + struct.pack("<f", v)


def vec(x, y, z):
    return f(x) + f(y) + f(z)


def u32(v):
    return struct.pack("<I", v)


def source_create(context, at=None, forward=None):
    """earshot_source_create (default settings), or earshot_source_create_at
    `at` facing `forward` (None: the default (0, 0, -1))."""
    p = bytes([SOURCE_CREATE, context, 0, 0])
    if at is None:
        return p + bytes([0])
    p += bytes([128]) + vec(*at)
    return p + (bytes([0]) if forward is None else bytes([128]) + vec(*forward))


def box_mesh(context, material=0, motion=0, bad_index=False):
    """Eight corners of [-2, 3]^3 (bit a of the vertex number: axis a at 3),
    twelve triangles, one material."""
    faces = [(0, 2, 6, 4), (1, 5, 7, 3), (0, 4, 5, 1), (2, 3, 7, 6), (0, 1, 3, 2), (4, 6, 7, 5)]
    tris = []
    for a, b, c, d in faces:
        tris += [(a, b, c), (a, c, d)]
    p = bytes([MESH_CREATE, 8, 12]) + bytes(8)  # 8 corners, none "any value"
    for t, tri in enumerate(tris):
        for i in tri:
            if bad_index and t == 11:
                p += bytes([245, 200]) + u32(1000)  # count(): index 1000
            else:
                p += bytes([0, i])
    p += bytes([1, material])  # one material name
    p += bytes(12 * 2)  # per-triangle material 0
    p += bytes([0, 0, 0])  # no transform, true struct_size, name "fuzz_mesh"
    p += bytes([0, 0, 0, 0])  # counts as made, per-triangle materials given
    p += bytes([0, motion, context])
    return p


def process(context, frames, inputs, hostile=None, channels_byte=0, plain=True, step=True):
    """An audio block; step=False: the block alone (inside another step)."""
    p = (bytes([PROCESS]) if step else b"") + bytes([context]) + u32(frames) + bytes([0, inputs])
    for i in range(inputs):
        if hostile is not None and i == 0:
            p += bytes([128]) + u32(hostile[0]) + f(hostile[1])
        else:
            p += bytes([0])
    p += bytes([channels_byte])
    if context == 0:
        p += bytes([0 if plain else 200])
    return p


def game_loop(context):
    p = bytes([SCENE_CREATE, context, 0, 0])
    p += box_mesh(context)
    p += bytes([ADD_OR_REMOVE_MESH, 0, 0, 0, COMMIT, 0, SET_SCENE, context, 0])
    p += source_create(context)
    p += source_create(context, at=(-1.0, 1.0, 2.0), forward=(0.0, 0.0, 1.0))
    p += bytes([SOURCE_MOVE, 0, 0]) + vec(1.0, 0.5, -1.5)
    p += bytes([SOURCE_MOVE, 1, 0]) + vec(-1.0, 1.0, 2.0)
    p += bytes([LISTENER]) + vec(0.2, 0.1, 0.3) + bytes([0, 0, context])
    p += bytes([SIMULATE, context, 0])
    p += process(context, 64, 2)
    p += process(context, 128, 2, plain=False)
    p += bytes([GET_IR, 0, 0, 0, 0])
    p += bytes([COMPUTE_IR, 0, context, 0, 0, 0])
    p += bytes([INFO, context, 0, 0])
    return p


def gltf_and_movable():
    p = bytes([SCENE_CREATE, 1, 0, 0])
    p += bytes([LOAD_GLTF, 0, 200, 0, 0, 0])  # shoebox.gltf with its material map
    p += bytes([SCENE_CREATE, 1, 0, 0, LOAD_GLTF, 0, 0, 1, 0, 1])  # its node "room" movable, in a second scene
    p += bytes([SCENE_RELEASE, 1])
    p += box_mesh(1, material=0, motion=1)  # a movable concrete box
    p += bytes([ADD_OR_REMOVE_MESH, 0, 0, 0, COMMIT, 0, SET_SCENE, 1, 0])
    p += source_create(1) + bytes([SOURCE_MOVE, 0, 0]) + vec(0.5, 0.5, 0.5)
    p += bytes([SIMULATE, 1, 1])
    # Row-major 3x4: identity, translated 0.25 m along x; then read back.
    p += bytes([TRANSFORM]) + bytes(16) + bytes([0]) + f(0.25) + bytes([0, 0, 0, 0])
    p += bytes([COMMIT, 0, SIMULATE, 1, 0, FIND_MESH, 0, 0])
    p += process(1, 200, 1)
    p += bytes([GET_IR, 0, 0, 0, 0])
    # The simulation thread at 50 Hz, all sources a step, three blocks.
    p += bytes([SIMULATION_THREAD, 1, 0, 49, 0, 3])
    for _ in range(3):
        p += process(1, 64, 1, step=False)
    return p


def hostile():
    p = bytes([SCENE_CREATE, 0, 0, 0])
    p += box_mesh(0, bad_index=True)  # refused: index 1000 of 8 vertices
    p += box_mesh(0, material=5)  # "no such material": refused when added
    p += bytes([ADD_OR_REMOVE_MESH, 0, 0, 0])
    p += bytes([ADD_OR_REMOVE_MESH, 0, 0, 0])  # twice
    p += source_create(0) + bytes([SOURCE_MOVE, 0, 0]) + vec(NAN, 0.0, 0.0)
    p += source_create(0, at=(NAN, 0.0, 0.0))  # refused: nothing created
    p += source_create(0, at=(0.0, 0.0, 2e6))  # farther than 1e6 m
    p += source_create(0, at=(1.0, 0.0, 0.0), forward=(0.0, 0.0, 0.0))
    p += bytes([LISTENER]) + vec(0.0, 0.0, 0.0) + bytes([200]) + vec(0.0, 1.0, 0.0) + bytes([0, 0])
    p += process(0, 64, 1, hostile=(10, NAN))
    p += process(0, 64, 1, hostile=(3, 3.4e38))
    p += bytes([SIMULATE, 0, 0, MEMORY_LIMIT, 1, SIMULATE, 0, 0, COMPUTE_IR, 0, 0])
    p += source_create(0)  # past a 1-byte limit
    p += bytes([NEW_CONTEXT]) + bytes([200]) + f(1e9) + bytes(12)
    return p


def failing_allocator():
    """Fresh contexts whose allocator gives 0, 1, .. 4 handles: the context,
    then a scene, a mesh and a source each made or refused."""
    p = b""
    for allowed in range(5):
        # Rate, block, slots, IR length, rays, bounces as the fuzzer's defaults;
        # image-source order, threads, distance, order, output, trace, HRTF
        # (Pulse), struct_size: defaults; then the allocator and its count.
        p += bytes([NEW_CONTEXT]) + bytes(14) + bytes([200, allowed])
    return p


def main():
    os.makedirs(OUT, exist_ok=True)
    seeds = {"game_loop_binaural.bin": game_loop(0), "game_loop_ambisonic.bin": game_loop(1),
             "gltf_and_movable.bin": gltf_and_movable(), "hostile_arguments.bin": hostile(),
             "failing_allocator.bin": failing_allocator()}
    for name, data in seeds.items():
        with open(os.path.join(OUT, name), "wb") as out:
            out.write(data)
        print(name, len(data), "bytes")


if __name__ == "__main__":
    main()
