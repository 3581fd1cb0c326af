"""Batch throughput of the Python package against one thread and against
the C++ CLI, measured side by side in one run (issue 18):

    /usr/bin/python3 python/benchmarks/bench_batch.py [--pairs 16] [--repeats 3] [--quality balanced]
        [--geometry samples/shoebox/shoebox.gltf --material-map samples/shoebox/materials_map.json]

Prints, per receiver: the CLI's median `time_ms.pipeline` (`earshot ir`, all
cores, --repeats runs), ir_batch's IRs per second with 1 thread and with all
cores (median of --repeats), the speed-up, and the batch's wall time per IR
over the CLI's pipeline time. Same pairs, same seeds throughout.
"""
import argparse
import json
import os
import statistics
import subprocess
import sys
import tempfile
import time

import numpy as np

HERE = os.path.dirname(os.path.abspath(__file__))
ROOT = os.path.normpath(os.path.join(HERE, "..", ".."))


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--pairs", type=int, default=16)
    ap.add_argument("--repeats", type=int, default=3)
    ap.add_argument("--quality", default="balanced")
    ap.add_argument("--geometry", default=os.path.join(ROOT, "samples/shoebox/shoebox.gltf"))
    ap.add_argument("--material-map", default=os.path.join(ROOT, "samples/shoebox/materials_map.json"))
    ap.add_argument("--cli", default=os.path.join(ROOT, "build/tools/earshot"))
    ap.add_argument("--receivers", default="omni,binaural")
    a = ap.parse_args()
    import earshot
    scene = earshot.Scene(a.geometry, material_map=a.material_map)
    lo, hi = (np.array(b) for b in scene.bounds)
    rng = np.random.default_rng(1)
    pairs = []
    while len(pairs) < a.pairs:
        s, l = rng.uniform(lo + 0.5, hi - 0.5), rng.uniform(lo + 0.5, hi - 0.5)
        if scene.contains(s) is not False and scene.contains(l) is not False and np.linalg.norm(s - l) > 1:
            pairs.append((tuple(s), tuple(l)))
    cores = os.cpu_count()
    print(f"{a.geometry}: {scene.triangle_count} triangles, {a.pairs} pairs, quality {a.quality}, {cores} cores")
    results = {}
    for receiver in a.receivers.split(","):
        # The CLI: one process per IR (loads scene and HRTF each time); its
        # own time_ms.pipeline is the compute time without the loading.
        cli_ms = []
        with tempfile.TemporaryDirectory() as d:
            for k in range(a.repeats):
                s, l = pairs[k % len(pairs)]
                js = os.path.join(d, "s.json")
                subprocess.run([a.cli, "ir", a.geometry, "--material-map", a.material_map,
                                "--source", ",".join(map(repr, s)), "--listener", ",".join(map(repr, l)),
                                "--receiver", receiver, "--quality", a.quality, "--seed", str(1 + k),
                                "-o", os.path.join(d, "x.wav"), "--json", js], check=True,
                               capture_output=True)
                with open(js) as f:
                    cli_ms.append(json.load(f)["time_ms"]["pipeline"])
        scene.ir_batch(pairs[:2], receiver=receiver, quality=a.quality, threads=1)  # HRTF loaded, warm
        rates = {}
        for threads in (1, 0):
            walls = []
            for _ in range(a.repeats):
                t0 = time.perf_counter()
                scene.ir_batch(pairs, receiver=receiver, quality=a.quality, seed=1, threads=threads)
                walls.append(time.perf_counter() - t0)
            rates[threads] = a.pairs / statistics.median(walls)
        cli = statistics.median(cli_ms)
        per_ir_ms = 1000.0 / rates[0]
        results[receiver] = {"cli_pipeline_ms": cli, "batch_1_thread_irs_per_s": rates[1],
                             "batch_all_cores_irs_per_s": rates[0], "speedup": rates[0] / rates[1],
                             "batch_ms_per_ir": per_ir_ms, "batch_ms_per_ir_over_cli": per_ir_ms / cli}
        r = results[receiver]
        print(f"{receiver:9s} CLI pipeline {cli:7.1f} ms | batch 1 thread {rates[1]:6.2f} IR/s, {cores} threads "
              f"{rates[0]:6.2f} IR/s: speed-up {r['speedup']:.2f}x | batch {per_ir_ms:6.1f} ms per IR = "
              f"{r['batch_ms_per_ir_over_cli']:.2f}x the CLI's pipeline")
    print(json.dumps(results))


if __name__ == "__main__":
    sys.exit(main())
