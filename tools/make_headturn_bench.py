#!/usr/bin/env python3
"""Writes the head-turn benchmark of issue 15 into a folder: 10 s, four still
sources (talker, guitar and two more loops) in the furnished sample room
(24k triangles), the listener in place turning at 90 degrees a second,
balanced quality. With ambisonic reflections each source is simulated once;
with binaural ones (--ambisonic-order 0) every 5 degrees of turn. Pure Python 3.

    python3 tools/make_headturn_bench.py /tmp/headturn
    build/tools/earshot render /tmp/headturn/scene.json -o /tmp/headturn/out.wav --threads 2
"""
import math
import os
import sys

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import make_render_bench as rb  # noqa: E402  (its loop() and the room's files)


def main():
    out = sys.argv[1] if len(sys.argv) > 1 else 'headturn'
    seconds = 10
    os.makedirs(out, exist_ok=True)
    rb.loop(os.path.join(rb.ROOT, 'samples/two_rooms/voice.wav'), os.path.join(out, 'voice.wav'), seconds)
    rb.loop(os.path.join(rb.ROOT, 'samples/hall/guitar.wav'), os.path.join(out, 'guitar.wav'), seconds)
    room = os.path.join(rb.ROOT, 'samples/furnished_room')
    import shutil
    for name in ('furnished_room.glb', 'materials_map.json'):
        shutil.copyfile(os.path.join(room, name), os.path.join(out, name))
    # 90 degrees a second about +z, keyframes every 0.25 s (22.5 degrees).
    keys = []
    for k in range(4 * seconds + 1):
        t = 0.25 * k
        a = math.radians(90.0 * t)
        keys.append({"t": t, "position": [5, 3.5, 1.2], "forward": [math.cos(a), math.sin(a), 0], "up": [0, 0, 1]})
    sources = [
        {"name": "talker", "audio": "voice.wav", "position": [7, 3.5, 1.5]},
        {"name": "guitar", "audio": "guitar.wav", "position": [3, 5.0, 1.0]},
        {"name": "talker2", "audio": "voice.wav", "position": [4, 1.5, 1.6], "gain_db": -3},
        {"name": "guitar2", "audio": "guitar.wav", "position": [6.5, 5.5, 1.1], "gain_db": -3},
    ]
    scene = {
        "geometry": 'furnished_room.glb',
        "material_map": 'materials_map.json',
        "listener": {"path": keys},
        "sources": sources,
        "settings": {"quality": "balanced", "duration": seconds},
    }
    import json
    with open(os.path.join(out, 'scene.json'), 'w') as f:
        json.dump(scene, f, indent=1)
    print('wrote', os.path.join(out, 'scene.json'))


if __name__ == '__main__':
    main()
