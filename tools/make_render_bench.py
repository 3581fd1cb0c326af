#!/usr/bin/env python3
"""Writes the render benchmark of issue 7 into a folder: 60 s of two sources
circling the listener in the furnished sample room (a talker and a guitar,
60 s loops of samples/two_rooms/voice.wav and guitar.wav). Pure Python 3.

    python3 tools/make_render_bench.py /tmp/bench60
    build/tools/earshot render /tmp/bench60/scene.json -o /tmp/bench60/out.wav
"""
import json
import math
import os
import shutil
import sys
import wave

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))


def loop(src, dst, seconds):
    with wave.open(src, 'rb') as w:
        params, data = w.getparams(), w.readframes(w.getnframes())
    frames = int(seconds * params.framerate)
    size = frames * params.sampwidth * params.nchannels
    with wave.open(dst, 'wb') as out:
        out.setparams(params)
        out.writeframes((data * (size // len(data) + 1))[:size])


def circle(cx, cy, radius, z, period, duration, phase=0.0):
    keys = []
    for k in range(int(duration * 2) + 1):
        t = 0.5 * k
        a = 2 * math.pi * t / period + phase
        keys.append({"t": t, "position": [cx + radius * math.cos(a), cy + radius * math.sin(a), z]})
    return keys


def main():
    out = sys.argv[1] if len(sys.argv) > 1 else 'bench60'
    os.makedirs(out, exist_ok=True)
    loop(os.path.join(ROOT, 'samples/two_rooms/voice.wav'), os.path.join(out, 'voice60.wav'), 60)
    loop(os.path.join(ROOT, 'samples/hall/guitar.wav'), os.path.join(out, 'guitar60.wav'), 60)
    room = os.path.join(ROOT, 'samples/furnished_room')
    # The scene's files sit beside it: references may not leave its folder.
    for name in ('furnished_room.glb', 'materials_map.json'):
        shutil.copyfile(os.path.join(room, name), os.path.join(out, name))
    scene = {
        "geometry": 'furnished_room.glb',
        "material_map": 'materials_map.json',
        "listener": {"position": [5, 3.5, 1.2], "forward": [1, 0, 0], "up": [0, 0, 1]},
        "sources": [
            {"name": "talker", "audio": "voice60.wav", "path": circle(5, 3.5, 2.0, 1.5, 15, 60)},
            {"name": "guitar", "audio": "guitar60.wav", "path": circle(5, 3.5, 2.5, 1.0, 20, 60, math.pi)},
        ],
        "settings": {"quality": "balanced", "duration": 60},
    }
    with open(os.path.join(out, 'scene.json'), 'w') as f:
        json.dump(scene, f, indent=1)
    print('wrote', os.path.join(out, 'scene.json'))


if __name__ == '__main__':
    main()
