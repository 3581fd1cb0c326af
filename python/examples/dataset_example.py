"""A small IR dataset, end to end (run it as a script, or cell by cell in a
notebook: the `# %%` markers split it):

    /usr/bin/python3 python/examples/dataset_example.py [-o /tmp/earshot-example] [--count 60] [--in-process]

1. writes a spec (10 generated shoebox rooms with random materials and the
   sample shoebox), 2. makes the dataset on a Dask LocalCluster, 3. plots
   the EDT and T30 distributions at 1 kHz (matplotlib, to a PNG), 4. checks
   a few IRs: their metrics, analysed again from the loaded samples, equal
   the manifest's, and their T30 lies near Eyring's for generated rooms.
"""
# %% Set-up
import argparse
import json
import math
import os
import shutil

import numpy as np

import earshot
from earshot import analysis, dataset

ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
ap.add_argument("-o", "--output", default="/tmp/earshot-example")
ap.add_argument("--count", type=int, default=60)
ap.add_argument("--in-process", action="store_true", help="no Dask (quick checks)")
args = ap.parse_args()
root = os.path.normpath(os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", ".."))
work = args.output
shutil.rmtree(work, ignore_errors=True)
os.makedirs(work)

# %% 1. The spec
shutil.copy(os.path.join(root, "samples/shoebox/shoebox.gltf"), work)
shutil.copy(os.path.join(root, "samples/shoebox/materials_map.json"), work)
spec = {
    "rooms": [
        {"generator": "shoebox", "rooms": 10, "size_m": {"x": [3, 10], "y": [3, 8], "z": [2.5, 3.5]},
         "absorption": [0.03, 0.4], "scattering": [0.1, 0.6]},
        {"geometry": "shoebox.gltf", "material_map": "materials_map.json"},
    ],
    "count": args.count, "seed": 1, "receiver": "omni", "quality": "draft", "shard_size": 10,
    "positions": {"wall_distance_m": 0.5, "min_separation_m": 1.5},
}
with open(os.path.join(work, "spec.json"), "w") as f:
    json.dump(spec, f, indent=1)

# %% 2. The dataset (a LocalCluster with one worker per core)
summary = dataset.make(os.path.join(work, "spec.json"), os.path.join(work, "data"), in_process=args.in_process,
                       workers=None, progress=True)
print(f"{summary['irs_made']} IRs, {summary['seconds_per_ir'] * 1000:.0f} ms per IR")

# %% 3. EDT and T30 at 1 kHz over the dataset
rows = [json.loads(line) for line in open(os.path.join(work, "data", "manifest.jsonl"))]
k = analysis.BANDS_HZ.index(1000.0)
edt = np.array([r["metrics"]["channels"][0]["EDT"][k] for r in rows], dtype=float)
t30 = np.array([r["metrics"]["channels"][0]["T30"][k] for r in rows], dtype=float)
import matplotlib
matplotlib.use("Agg")
import matplotlib.pyplot as plt
fig, ax = plt.subplots(1, 2, figsize=(9, 3.5))
ax[0].hist(edt[np.isfinite(edt)], bins=15)
ax[0].set_xlabel("EDT at 1 kHz (s)")
ax[1].hist(t30[np.isfinite(t30)], bins=15)
ax[1].set_xlabel("T30 at 1 kHz (s)")
for a in ax:
    a.set_ylabel("IRs")
fig.suptitle(f"{len(rows)} IRs in {len(set(r['room_index'] for r in rows))} rooms")
fig.tight_layout()
png = os.path.join(work, "edt_t30.png")
fig.savefig(png, dpi=100)
print(f"plotted {png}")

# %% 4. Checks on a few IRs
checked = 0
for i, samples, params in dataset.load(os.path.join(work, "data")):
    if i >= 5:
        break
    again = analysis.analyze(samples, params["sample_rate"])
    for m in analysis.METRICS:
        stored = np.array([np.nan if v is None else v for v in params["metrics"]["channels"][0][m]])
        assert np.allclose(again[m][0], stored, equal_nan=True), (i, m)
    room = params["room"]
    if "size_m" in room:  # a generated room: Eyring's T60 from its mean absorption at 1 kHz
        x, y, z = room["size_m"]
        areas = {"walls": 2 * (x + y) * z, "floor": x * y, "ceiling": x * y}
        s = sum(areas.values())
        alpha = sum(areas[w] * room["materials"][w]["absorption"][3] for w in areas) / s
        eyring = 0.161 * x * y * z / (-s * math.log(1 - alpha))
        print(f"IR {i}: T30 {again['T30'][0, k]:.2f} s, Eyring {eyring:.2f} s (mean absorption {alpha:.2f})")
    checked += 1
print(f"checked {checked} IRs: the manifest's metrics are the samples' own")
