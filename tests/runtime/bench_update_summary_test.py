#!/usr/bin/env python3
"""tools/bench_update_summary.py on a known log: each criterion's figures
and status computed from the lines that carry them, and a log without
them says "not measured". Run by ctest (tools_bench_update_summary)."""
import os
import sys

sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), '..', '..', 'tools'))
import bench_update_summary as summary  # noqa: E402

LOG = """# 2026-11-27T05:13:37Z 2 cores, load 3.18 2.15 1.53
## shoebox/shoebox.gltf
trace scene=samples/shoebox/shoebox.gltf triangles=12 rays=16384 bounces=12 threads=2 runs=9 trace_ms=55.79 min_ms=46.10
embree mode=single queries=440454 (nearest=440454 shadow=0) hits=437755 ms=16.90 mrays_per_s=26.1
embree mode=packet8 queries=440454 (nearest=440454 shadow=0) hits=437755 ms=16.44 mrays_per_s=26.8
ratio earshot_per_query/embree_per_query=3.41 (best plain mode: packet8; earshot 127.1 ns, embree 37.3 ns per query)
synth scene=samples/shoebox/shoebox.gltf quality=balanced ir_seconds=2.00 arrivals=63 runs=9 threads=1 binaural_ms=5.12 omni_ms=1.62
synth per output channel: binaural_ms=2.56 omni_ms=1.62 ambisonic1_ms=1.10 ambisonic3_ms=0.69
earshot ir (binaural, one-shot process, cache off, median of 3): trace_ms=47.4 early_reflections_ms=9.9 tail_ms=9.9 synthesis_ms=109.9
earshot ir (binaural, one-shot process, cache warm, median of 3): trace_ms=42.2 early_reflections_ms=0.1 tail_ms=2.2 synthesis_ms=37.7
## furnished_room/furnished_room.glb
trace scene=samples/furnished_room/furnished_room.glb triangles=23992 rays=16384 bounces=12 threads=2 runs=9 trace_ms=75.33
embree mode=stream queries=701133 (nearest=520530 shadow=180603) hits=546286 ms=42.32 mrays_per_s=16.6
embree mode=packet8 queries=701133 (nearest=520530 shadow=180603) hits=546286 ms=39.70 mrays_per_s=17.7
ratio earshot_per_query/embree_per_query=1.91 (best plain mode: packet8; earshot 108.4 ns, embree 56.6 ns per query)
synth scene=samples/furnished_room/furnished_room.glb quality=balanced ir_seconds=2.00 arrivals=50 binaural_ms=4.36 omni_ms=1.39
synth per output channel: binaural_ms=3.18 omni_ms=1.39 ambisonic1_ms=0.90 ambisonic3_ms=0.61
earshot ir (binaural, one-shot process, cache warm, median of 3): trace_ms=81.8 early_reflections_ms=6.5 tail_ms=2.4 synthesis_ms=38.9
## render benchmark (tools/make_render_bench.py: 60 s, two sources circling, furnished room)
render wall_s=7.85,8.06,8.05 median_s=8.05
## runtime, trace shared
runtime scene=x sources=32 worst_block_pct_of_period=46.0 p99_block_pct=30.2 worst_block_cpu_pct=29.8 max_block_cpu_pct=57.7 per_source_update_hz=3.10
machine_steal_ms=30 (time the hypervisor took)
## runtime, trace per-source
runtime scene=x sources=32 worst_block_pct_of_period=91.0 per_source_update_hz=0.17
machine_steal_ms=10 (time the hypervisor took)
## runtime, trace shared, simulation on all 2 cores
runtime scene=x sources=32 worst_block_pct_of_period=37.1 per_source_update_hz=5.20
"""


def rows(text):
    return {line.split(' | ')[0].lstrip('| '): line.split(' | ')[1:] for line in text.splitlines()[2:]}


def main():
    t = rows(summary.table(*summary.parse(LOG.splitlines(True))))
    # The default threads' rate decides (the all-cores one is information).
    assert t['runtime, 32 moving sources: >= 5 IR updates per second per source'] == \
        ['3.10 (default threads); 5.20 on all cores', 'not met |'], t
    # The shared trace's default run, not the per-source one's 91 %.
    assert t['runtime: worst audio block < 50 % of its period'] == \
        ['wall 46.0 %, its CPU 29.8 %, most CPU of any block 57.7 %, p99 30.2 %, steal 30 ms', 'met |'], t
    assert t['render benchmark <= 10 s'] == ['median 8.05 s', 'met |'], t
    # One channel over 3 ms (furnished room's binaural 3.18) fails it.
    assert t['synthesis <= 3 ms per output channel (2 s IR)'][1] == 'not met |', t
    assert t['tracer per query <= 1.3x plain Embree (best mode)'] == ['furnished_room 1.91x, shoebox 3.41x', 'not met |']
    # Update: bench trace + the warm `earshot ir`'s early and tail (not the
    # cold run's 9.9) + bench synth's binaural IR, against twice the best
    # Embree mode (packet8, not stream or single).
    update = t['balanced binaural update (trace + early + tail + synthesis) <= 2x the Embree limit']
    assert update[0] == ('furnished_room: 75.3 + 6.5 + 2.4 + 4.4 = 88.6 ms against 2 x 39.7 (2.23x the Embree limit); '
                         'shoebox: 55.8 + 0.1 + 2.2 + 5.1 = 63.2 ms against 2 x 16.4 (3.84x the Embree limit)'), update
    assert update[1] == 'not met |'
    # A log without the figures: every criterion "not measured".
    empty = rows(summary.table(*summary.parse(['# nothing\n'])))
    assert all(v[-1] == 'not measured |' for v in empty.values()), empty
    print('bench_update_summary: ok')
    return 0


if __name__ == '__main__':
    sys.exit(main())
