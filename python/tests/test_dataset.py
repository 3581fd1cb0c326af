"""earshot.dataset: the same IRs whatever the workers, resumable after a
kill, positions that keep their distances, specs checked."""
import json
import os
import shutil
import signal
import subprocess
import sys
import time

import numpy as np
import pytest

import earshot
from earshot import dataset
from conftest import SHOEBOX, SHOEBOX_MAP, SOURCE_DIR


def make_spec(folder, **over):
    shutil.copy(SHOEBOX, folder / "shoebox.gltf")
    shutil.copy(SHOEBOX_MAP, folder / "map.json")
    spec = {"rooms": [{"geometry": "shoebox.gltf", "material_map": "map.json"},
                      {"generator": "shoebox", "rooms": 2, "size_m": {"x": [4, 6], "y": [3, 5], "z": [2.5, 3]}},
                      {"generator": "shoebox", "absorption": [0.1, 0.4]}],
            "count": 10, "seed": 3, "quality": "draft", "shard_size": 3,
            "ir_options": {"rays": 1024, "length": 0.5}}
    spec.update(over)
    p = folder / "spec.json"
    p.write_text(json.dumps(spec))
    return p


def loaded(d):
    return [(i, x, p) for i, x, p in dataset.load(d)]


def assert_same(a, b):
    assert [i for i, _, _ in a] == [i for i, _, _ in b]
    for (i, x, p), (_, y, q) in zip(a, b):
        assert np.array_equal(x, y), i
        assert p["source"] == q["source"] and p["listener"] == q["listener"] and p["seed"] == q["seed"]


@pytest.fixture(scope="module")
def reference(tmp_path_factory):
    folder = tmp_path_factory.mktemp("ref")
    spec = make_spec(folder)
    s = dataset.make(spec, folder / "out", in_process=True, progress=False)
    assert s["irs_made"] == 10 and s["shards"] == 4
    return folder, loaded(folder / "out")


def test_manifest_and_params(reference):
    folder, irs = reference
    assert [i for i, _, _ in irs] == list(range(10))
    rows = [json.loads(line) for line in (folder / "out" / "manifest.jsonl").read_text().splitlines()]
    assert [r["id"] for r in rows] == list(range(10))
    for (i, x, p), row in zip(irs, rows):
        assert x.dtype == np.float32 and x.shape == (1, 24000)
        assert row["seed"] == 3 + i and row["rays"] == 1024 and row["quality"] == "draft"
        assert row["room_index"] == i % 4
        assert set(row["metrics"]["channels"][0]) == {"EDT", "T20", "T30", "C50", "C80", "D50", "Ts"}
        assert "pipeline" in row["time_ms"]
        assert p == row


def test_positions_keep_their_distances(reference):
    folder, irs = reference
    for i, _, p in irs:
        room = p["room"]
        if "size_m" in room:
            size = np.array(room["size_m"])
            for pt in (p["source"], p["listener"]):
                assert np.all(np.array(pt) >= 0.5 - 1e-9) and np.all(np.array(pt) <= size - 0.5 + 1e-9)
        assert np.linalg.norm(np.subtract(p["source"], p["listener"])) >= 1.0
        assert p["warnings"] == []
    # Rooms drawn from the distributions differ from each other.
    sizes = {tuple(p["room"]["size_m"]) for _, _, p in irs if "size_m" in p["room"]}
    assert len(sizes) == 3


def test_same_irs_on_a_two_worker_local_cluster(reference, tmp_path):
    folder, irs = reference
    s = dataset.make(folder / "spec.json", tmp_path / "out", workers=2, progress=False)
    assert s["irs_made"] == 10
    assert_same(loaded(tmp_path / "out"), irs)


def test_same_irs_through_a_running_scheduler(reference, tmp_path):
    # `--scheduler ADDRESS`: a cluster that runs apart from the command (here
    # a LocalCluster of one worker process, reached by its address only).
    from dask.distributed import LocalCluster
    folder, irs = reference
    cluster = LocalCluster(n_workers=1, threads_per_worker=1, processes=True, scheduler_port=0,
                           dashboard_address=":0", silence_logs=40)
    try:
        s = dataset.make(folder / "spec.json", tmp_path / "out", scheduler=cluster.scheduler_address,
                         progress=False)
    finally:
        cluster.close()
    assert s["irs_made"] == 10 and s["shards_made"] == 4
    assert_same(loaded(tmp_path / "out"), irs)


def test_killed_run_resumes_to_the_same_irs(reference, tmp_path):
    folder, irs = reference
    out = tmp_path / "out"
    p = subprocess.Popen([sys.executable, "-m", "earshot", "dataset", str(folder / "spec.json"), "-o", str(out),
                          "--in-process", "--quiet"], stdout=subprocess.DEVNULL, stderr=subprocess.PIPE)
    first = out / "shards" / "shard-00000.h5"
    deadline = time.time() + 120
    while not first.exists() and p.poll() is None and time.time() < deadline:
        time.sleep(0.02)
    last_before_kill = (out / "shards" / "shard-00003.h5").exists()
    p.send_signal(signal.SIGKILL)
    p.wait()
    assert first.exists() and not last_before_kill  # killed mid-run
    assert not (out / "manifest.jsonl").exists() or p.returncode == 0
    # A half-written shard as a kill leaves it: never taken for complete.
    (out / "shards" / "shard-00003.h5.tmp-12345").write_bytes(b"\x89HDF\r\n\x1a\n" + b"\0" * 100)
    with pytest.raises(ValueError, match="incomplete"):
        loaded(out)
    partial = list(dataset.load(out, partial=True))
    assert partial and all(np.array_equal(x, irs[i][1]) for i, x, _ in partial)
    s = dataset.make(folder / "spec.json", out, in_process=True, progress=False)
    assert s["shards_reused"] >= 1 and s["shards_made"] + s["shards_reused"] == 4
    assert not any(".tmp-" in n for n in os.listdir(out / "shards"))
    assert_same(loaded(out), irs)


def test_a_damaged_shard_is_made_again(reference, tmp_path):
    folder, irs = reference
    out = tmp_path / "out"
    shutil.copytree(folder / "out", out)
    (out / "shards" / "shard-00001.h5").write_bytes(b"garbage")
    s = dataset.make(folder / "spec.json", out, in_process=True, progress=False)
    assert s["shards_made"] == 1
    assert_same(loaded(out), irs)


@pytest.mark.parametrize("fmt", ["hdf5", "wav"])
def test_a_shard_that_lost_an_ir_is_made_again(reference, tmp_path, fmt):
    # A shard whose manifest is whole but one of whose IRs is gone, cut or
    # of another shape is not complete: load says so, and make makes it
    # again (before, make kept it and load said to delete it by hand).
    import h5py
    folder, irs = reference
    spec = make_spec(tmp_path, format=fmt)
    out = tmp_path / "out"
    dataset.make(spec, out, in_process=True, progress=False)
    shard = out / "shards" / ("shard-00001.h5" if fmt == "hdf5" else "shard-00001")
    if fmt == "hdf5":
        damage = [lambda f: f.__delitem__("ir/00000004"),
                  lambda f: (f.__delitem__("ir/00000004"),
                             f.create_dataset("ir/00000004", data=np.zeros((1, 2, 3), np.float32))),
                  lambda f: (f.__delitem__("ir/00000004"),
                             f.create_dataset("ir/00000004", data=np.zeros((1, 100), np.float32))),
                  lambda f: (f.__delitem__("ir/00000004"),
                             f.create_dataset("ir/00000004", data=np.zeros((1, 24000), np.float64)))]
    else:
        wav = shard / "ir-00000004.wav"
        damage = [lambda _: wav.unlink(),
                  lambda _: wav.write_bytes(wav.read_bytes()[:1000]),
                  lambda _: wav.write_bytes(wav.read_bytes() + b"\0" * 4),
                  lambda _: (wav.unlink(), wav.mkdir())]
    for j, hurt in enumerate(damage):
        if fmt == "hdf5":
            with h5py.File(shard, "r+") as f:
                hurt(f)
        else:
            hurt(None)
        with pytest.raises(ValueError, match=r"shard 1 is missing, incomplete or damaged \(run make again"):
            loaded(out)
        s = dataset.make(spec, out, in_process=True, progress=False)
        assert (s["shards_made"], s["shards_reused"]) == (1, 3), j
        assert not any(".tmp-" in n for n in os.listdir(out / "shards"))
        assert_same(loaded(out), irs)


def test_wav_format(reference, tmp_path):
    folder, irs = reference
    spec = make_spec(tmp_path, format="wav")
    dataset.make(spec, tmp_path / "out", in_process=True, progress=False)
    assert_same(loaded(tmp_path / "out"), irs)
    assert (tmp_path / "out" / "shards" / "shard-00000" / "ir-00000000.wav").exists()


@pytest.mark.parametrize("over,text", [
    ({"count": 0}, "count"),
    ({"colour": 1}, "unknown"),
    ({"rooms": []}, "rooms"),
    ({"rooms": [{"geometry": "../escape.gltf"}]}, "outside"),
    ({"rooms": [{"geometry": "/etc/passwd"}]}, "outside"),
    ({"rooms": [{"generator": "sphere"}]}, "generator"),
    ({"rooms": [{"generator": "shoebox", "size_m": {"x": [5, 1], "y": [3, 4], "z": [2, 3]}}]}, "size_m"),
    ({"rooms": [{"generator": "shoebox", "materials": {"walls": ["unobtainium"], "floor": ["brick"],
                                                       "ceiling": ["brick"]}}]}, "unobtainium"),
    ({"receiver": "ambisonic"}, "receiver"),
    ({"ir_options": {"rays": -1}}, "rays"),
    ({"positions": {"wall_distance_m": -1}}, "wall_distance"),
    ({"rooms": [{"geometry": "shoebox\0.gltf"}]}, "geometry: expected a file name"),
    ({"ir_options": {"hrtf": "../escape.sofa"}}, "ir_options.hrtf: .* leads outside"),
    ({"ir_options": {"hrtf": "/etc/passwd"}}, "ir_options.hrtf: .* leads outside"),
    ({"ir_options": {"hrtf": "none.sofa"}}, "ir_options.hrtf: .* is not a file"),
    ({"ir_options": {"colour": 1}}, r"ir_options: unknown option\(s\) \['colour'\]"),
    ({"ir_options": {"length": "long"}}, "ir_options: length"),
])
def test_bad_specs_are_refused(tmp_path, over, text):
    (tmp_path / "sub").mkdir()
    spec = make_spec(tmp_path / "sub", **over)
    with pytest.raises(ValueError, match=text):
        dataset.make(spec, tmp_path / "out", in_process=True, progress=False)


def test_names_from_the_spec_stay_on_one_line(tmp_path):
    (tmp_path / "sub").mkdir()
    spec = make_spec(tmp_path / "sub", rooms=[{"geometry": "room\nFAKE LOG LINE.gltf"}])
    with pytest.raises(ValueError, match="is not a file") as e:
        dataset.make(spec, tmp_path / "out", in_process=True, progress=False)
    assert "\n" not in str(e.value) and "room\\nFAKE" in str(e.value)


def test_a_folder_of_another_spec_is_not_mixed(reference, tmp_path):
    folder, _ = reference
    out = tmp_path / "out"
    shutil.copytree(folder / "out", out)
    spec = make_spec(tmp_path, seed=4)
    with pytest.raises(ValueError, match="different spec"):
        dataset.make(spec, out, in_process=True, progress=False)


def test_positions_that_cannot_be_placed_say_so(tmp_path):
    spec = make_spec(tmp_path, rooms=[{"generator": "shoebox", "size_m": {"x": [2, 2], "y": [2, 2],
                                                                          "z": [2, 2]}}],
                     positions={"wall_distance_m": 0.9, "min_separation_m": 1.0}, count=1)
    r = subprocess.run([sys.executable, "-m", "earshot", "dataset", str(spec), "-o", str(tmp_path / "o"),
                        "--in-process", "--quiet"], capture_output=True, text=True, timeout=120)
    assert r.returncode == 2 and "no pair" in r.stderr and "Traceback" not in r.stderr


def test_outputs_never_replace_inputs(tmp_path):
    spec = make_spec(tmp_path)
    # The spec's own folder as the output: spec.json there is the input.
    with pytest.raises(ValueError, match="replace an input"):
        dataset.make(spec, tmp_path, in_process=True, progress=False)
    assert json.loads(spec.read_text())["count"] == 10


def test_import_earshot_alone_gives_the_dataset_functions(tmp_path):
    # docs/python.md: `import earshot` then earshot.dataset.make / load, in a
    # fresh interpreter (this one imported earshot.dataset above). The module
    # is loaded on first use, not by `import earshot`.
    spec = make_spec(tmp_path, count=2, shard_size=2)
    code = ("import sys, earshot\n"
            "assert 'earshot.dataset' not in sys.modules\n"
            "assert 'dataset' in earshot.__all__ and 'dataset' in dir(earshot) and 'Scene' in dir(earshot)\n"
            f"earshot.dataset.make({str(spec)!r}, {str(tmp_path / 'out')!r}, in_process=True, progress=False)\n"
            f"print(sum(1 for _ in earshot.dataset.load({str(tmp_path / 'out')!r})))\n"
            "try:\n"
            "    earshot.no_such_thing\n"
            "except AttributeError as e:\n"
            "    print('AttributeError', e)\n")
    r = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120)
    assert r.returncode == 0, r.stderr
    lines = r.stdout.split("\n")
    assert lines[0] == "2"
    assert lines[1].startswith("AttributeError") and "no_such_thing" in lines[1]


def test_an_hrtf_in_ir_options_is_the_specs_file(tmp_path, monkeypatch):
    # Relative to the spec's folder, as the rooms' files are: not to the
    # folder the command (or a Dask worker) runs in. The caller's dict stays.
    folder = tmp_path / "spec"
    folder.mkdir()
    shutil.copy(os.path.join(SOURCE_DIR, "hrtf", "FHK_HRIR_L2354.sofa"), folder / "ears.sofa")
    make_spec(folder)
    spec = json.loads((folder / "spec.json").read_text())
    spec.update(rooms=spec["rooms"][:1], count=1, receiver="binaural", ir_options={"hrtf": "ears.sofa", "rays": 256,
                                                                                  "length": 0.2})
    resolved = dataset.resolve_spec(spec, str(folder))
    assert resolved["ir_options"]["hrtf"] == os.path.realpath(folder / "ears.sofa")
    assert spec["ir_options"]["hrtf"] == "ears.sofa"
    (folder / "spec.json").write_text(json.dumps(spec))
    elsewhere = tmp_path / "elsewhere"
    elsewhere.mkdir()
    monkeypatch.chdir(elsewhere)
    s = dataset.make(folder / "spec.json", tmp_path / "out", in_process=True, progress=False)
    assert s["irs_made"] == 1
    [(_, x, p)] = loaded(tmp_path / "out")
    assert x.shape[0] == 2 and p["receiver"] == "binaural"


def test_a_damaged_folder_is_a_clear_error_not_a_crash(reference, tmp_path):
    # What a damaged file makes load() allocate is checked first: an IR that
    # claims 2 x 2,000,000 samples (sparse, a few KB on disk; its manifest
    # row says so too) is refused under an 8 MiB limit before it is read.
    import h5py
    folder, irs = reference
    out = tmp_path / "out"
    shutil.copytree(folder / "out", out)
    with h5py.File(out / "shards" / "shard-00000.h5", "r+") as f:
        rows = json.loads(f["manifest"][()])
        rows[0]["channels"], rows[0]["frames"] = 2, 2_000_000
        del f["manifest"]
        f.create_dataset("manifest", data=json.dumps(rows))
        params = f["ir/00000000"].attrs["params"]
        del f["ir/00000000"]
        f.create_dataset("ir/00000000", shape=(2, 2_000_000), dtype="f4", chunks=(1, 4096))
        f["ir/00000000"].attrs["params"] = params
    before = earshot.memory_limit()
    try:
        earshot.set_memory_limit(8 << 20)
        with pytest.raises(ValueError, match=r"shard-00000.h5: IR 0 is damaged \(2 x 2000000 samples, over the "
                                             r"memory limit of 8.0 MiB"):
            loaded(out)
    finally:
        earshot.set_memory_limit(None if before == 1 << 30 else before)
    shutil.rmtree(out / "shards")
    shutil.copytree(folder / "out" / "shards", out / "shards")
    with h5py.File(out / "shards" / "shard-00000.h5", "r+") as f:
        f["ir/00000001"].attrs["params"] = "{not json"
    with pytest.raises(ValueError, match=r"IR 1 is damaged \(JSONDecodeError\)"):
        loaded(out)
    # The folder's own record: garbage, or JSON that is not one.
    for text in (b"\xff\xfe garbage", b"[1, 2]", b'{"hash": "x", "spec": {"count": 1e999}}'):
        (out / "spec.json").write_bytes(text)
        with pytest.raises(ValueError, match=r"spec.json: not a dataset's record") as e:
            loaded(out)
        assert "garbage" not in str(e.value)
        with pytest.raises(ValueError, match=r"spec.json: not a dataset's record"):
            dataset.make(folder / "spec.json", out, in_process=True, progress=False)


def test_a_cluster_holds_a_window_of_shards_not_all(tmp_path, monkeypatch):
    # make() keeps at most max(16, 4 x the cluster's threads) shards in flight
    # and releases each when done, so neither the command nor the cluster
    # holds every shard's rows (~12 KiB an IR: 11 GiB for a million IRs).
    # The client's live futures are counted at each submit.
    from dask.distributed import Client, LocalCluster
    spec = make_spec(tmp_path, rooms=[{"generator": "shoebox", "absorption": [0.3, 0.5]}], count=40,
                     shard_size=1, receiver="omni", ir_options={"rays": 64, "length": 0.1})
    live, submit = [], Client.submit

    def counting_submit(self, *args, **kwargs):
        live.append(len(self.futures))
        return submit(self, *args, **kwargs)
    monkeypatch.setattr(Client, "submit", counting_submit)
    cluster = LocalCluster(n_workers=1, threads_per_worker=1, processes=True, scheduler_port=0,
                           dashboard_address=":0", silence_logs=40)
    try:
        s = dataset.make(spec, tmp_path / "out", scheduler=cluster.scheduler_address, progress=False)
    finally:
        cluster.close()
    assert s["irs_made"] == 40 and len(live) == 40
    assert max(live) <= 16, live  # 39 without the window
    dataset.make(spec, tmp_path / "ref", in_process=True, progress=False)
    assert_same(loaded(tmp_path / "out"), loaded(tmp_path / "ref"))
    rows = [json.loads(line) for line in (tmp_path / "out" / "manifest.jsonl").read_text().splitlines()]
    assert [r["id"] for r in rows] == list(range(40))
