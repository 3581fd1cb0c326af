"""A dataset of IRs three ways, compared by earshot.dataset.load (issue 18):

    /usr/bin/python3 python/benchmarks/bench_dataset.py [--count 1000] [--workers 2] [--quality balanced]
        [--work /tmp/earshot-bench-dataset]

Spec: --count omni IRs at --quality in 3 rooms (the shoebox and furnished
room samples and one generated shoebox). Runs: (1) a LocalCluster of
--workers workers; (2) a LocalCluster of 1 worker; (3) --workers workers
killed (SIGKILL to the whole process group) once about 40 % of the shards
exist, then run again to finish. Prints the time per IR of each and whether
(2) and (3) load the same IRs as (1).
"""
import argparse
import json
import os
import shutil
import signal
import subprocess
import sys
import time

import numpy as np

HERE = os.path.dirname(os.path.abspath(__file__))
ROOT = os.path.normpath(os.path.join(HERE, "..", ".."))


def run(spec, out, workers, kill_at=None):
    cmd = [sys.executable, "-m", "earshot", "dataset", spec, "-o", out, "--workers", str(workers), "--quiet"]
    t0 = time.perf_counter()
    p = subprocess.Popen(cmd, stdout=subprocess.PIPE, start_new_session=True)
    if kill_at is not None:
        shards = os.path.join(out, "shards")
        while p.poll() is None:
            n = len([f for f in os.listdir(shards) if f.endswith(".h5")]) if os.path.isdir(shards) else 0
            if n >= kill_at:
                os.killpg(p.pid, signal.SIGKILL)
                p.wait()
                return None, time.perf_counter() - t0, n
            time.sleep(0.05)
    out_text, _ = p.communicate()
    if p.returncode != 0:
        raise SystemExit(f"{' '.join(cmd)} failed ({p.returncode})")
    return json.loads(out_text.decode().strip().splitlines()[-1]), time.perf_counter() - t0, None


def same(a, b):
    from earshot import dataset
    n = 0
    for (i, x, p), (j, y, q) in zip(dataset.load(a), dataset.load(b)):
        if i != j or not np.array_equal(x, y) or p["source"] != q["source"]:
            return False, n
        n += 1
    return True, n


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--count", type=int, default=1000)
    ap.add_argument("--workers", type=int, default=2)
    ap.add_argument("--quality", default="balanced")
    ap.add_argument("--shard-size", type=int, default=25)
    ap.add_argument("--work", default="/tmp/earshot-bench-dataset")
    ap.add_argument("--resume-only", action="store_true",
                    help="keep --work's finished runs (1) and (2); run (3) again")
    a = ap.parse_args()
    if not a.resume_only:
        shutil.rmtree(a.work, ignore_errors=True)
    else:
        shutil.rmtree(os.path.join(a.work, "killed"), ignore_errors=True)
    os.makedirs(a.work, exist_ok=True)
    for f in ("shoebox/shoebox.gltf", "furnished_room/furnished_room.glb"):
        shutil.copy(os.path.join(ROOT, "samples", f), a.work)
    shutil.copy(os.path.join(ROOT, "samples/shoebox/materials_map.json"), os.path.join(a.work, "shoebox_map.json"))
    shutil.copy(os.path.join(ROOT, "samples/furnished_room/materials_map.json"),
                os.path.join(a.work, "furnished_map.json"))
    spec = {"rooms": [{"geometry": "shoebox.gltf", "material_map": "shoebox_map.json"},
                      {"geometry": "furnished_room.glb", "material_map": "furnished_map.json"},
                      {"generator": "shoebox"}],
            "count": a.count, "seed": 1, "receiver": "omni", "quality": a.quality, "shard_size": a.shard_size}
    sp = os.path.join(a.work, "spec.json")
    with open(sp, "w") as f:
        json.dump(spec, f)
    shards = (a.count + a.shard_size - 1) // a.shard_size
    print(f"{a.count} {a.quality} omni IRs, 3 rooms, {shards} shards of {a.shard_size}, {os.cpu_count()} cores")
    if a.resume_only:
        _, wk, n = run(sp, os.path.join(a.work, "killed"), a.workers, kill_at=int(0.4 * shards))
        s3, w3, _ = run(sp, os.path.join(a.work, "killed"), a.workers)
        ok3, n3 = same(os.path.join(a.work, "w"), os.path.join(a.work, "killed"))
        print(f"killed after {wk:.1f} s with {n} shards whole, resumed: {s3['shards_reused']} shards reused, "
              f"{s3['shards_made']} made in {w3:.1f} s; same IRs: {ok3} ({n3} compared)")
        return 0 if ok3 else 1
    s1, w1, _ = run(sp, os.path.join(a.work, "w"), a.workers)
    print(f"{a.workers} workers: {w1:.1f} s wall ({w1 / a.count * 1000:.1f} ms per IR, incl. cluster start); "
          f"median pipeline {s1['median_pipeline_ms']:.1f} ms")
    s2, w2, _ = run(sp, os.path.join(a.work, "one"), 1)
    ok2, n2 = same(os.path.join(a.work, "w"), os.path.join(a.work, "one"))
    print(f"1 worker: {w2:.1f} s wall ({w2 / a.count * 1000:.1f} ms per IR); speed-up {w2 / w1:.2f}x; "
          f"same IRs as {a.workers} workers: {ok2} ({n2} compared)")
    _, wk, n = run(sp, os.path.join(a.work, "killed"), a.workers, kill_at=int(0.4 * shards))
    s3, w3, _ = run(sp, os.path.join(a.work, "killed"), a.workers)
    ok3, n3 = same(os.path.join(a.work, "w"), os.path.join(a.work, "killed"))
    print(f"killed after {wk:.1f} s with {n} shards whole, resumed: {s3['shards_reused']} shards reused, "
          f"{s3['shards_made']} made in {w3:.1f} s; same IRs: {ok3} ({n3} compared)")
    print(json.dumps({"workers": a.workers, "count": a.count, "wall_s": w1, "ms_per_ir": w1 / a.count * 1000,
                      "one_worker_wall_s": w2, "speedup": w2 / w1, "same_one_worker": ok2,
                      "killed_at_s": wk, "resumed_reused": s3["shards_reused"], "same_resumed": ok3}))
    return 0 if ok2 and ok3 else 1


if __name__ == "__main__":
    sys.exit(main())
