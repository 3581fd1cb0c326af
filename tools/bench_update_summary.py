#!/usr/bin/env python3
"""Issue 16's criteria from the output of tools/bench_update.sh, as a
markdown table: every figure measured in that one run (the Embree limit
beside the tracer, the render's median, the runtime's rates and blocks).
Pure Python 3.

    bash tools/bench_update.sh | tee update.log
    python3 tools/bench_update_summary.py update.log

bench_update.sh runs it at its end. A figure the log lacks is "-" and its
criterion "not measured".
"""
import re
import sys


def numbers(line):
    """key=value pairs of a report line, values as floats where they parse."""
    out = {}
    for key, value in re.findall(r'([a-z0-9_/]+)=([-0-9.]+)', line):
        try:
            out[key] = float(value)
        except ValueError:
            pass
    return out


def parse(lines):
    """The figures of one bench_update.sh log."""
    scenes = {}
    runtime = {}
    render = None
    scene = None
    section = None
    for raw in lines:
        line = raw.rstrip('\n')
        if line.startswith('## '):
            section = line[3:]
            scene = None
            if '/' in section and (section.endswith('.gltf') or section.endswith('.glb')):
                scene = scenes.setdefault(section.split('/')[0], {})
            continue
        f = numbers(line)
        if scene is not None:
            if line.startswith('trace scene=') and 'trace_ms' in f:
                scene['trace_ms'] = f['trace_ms']
            elif line.startswith('embree mode=') and 'ms' in f:
                scene['embree_ms'] = min(scene.get('embree_ms', float('inf')), f['ms'])
            elif line.startswith('ratio earshot_per_query/embree_per_query='):
                scene['ratio'] = f.get('earshot_per_query/embree_per_query')
            elif line.startswith('synth scene=') and 'binaural_ms' in f:
                scene['binaural_ir_ms'] = f['binaural_ms']
            elif line.startswith('synth per output channel:'):
                scene['per_channel'] = {k[:-3]: v for k, v in f.items() if k.endswith('_ms')}
            elif line.startswith('earshot ir (binaural') and 'cache warm' in line:
                scene['early_ms'] = f.get('early_reflections_ms')
                scene['tail_ms'] = f.get('tail_ms')
        elif line.startswith('render wall_s='):
            render = f.get('median_s')
        elif section and section.startswith('runtime, trace shared') and line.startswith('runtime scene='):
            key = 'all_cores' if 'all' in section else 'default'
            runtime[key] = f
        elif section and section.startswith('runtime, trace shared') and line.startswith('machine_steal_ms='):
            key = 'all_cores' if 'all' in section else 'default'
            runtime.setdefault(key, {})['steal_ms'] = f.get('machine_steal_ms')
    return scenes, runtime, render


def fmt(v, unit='', digits=2):
    return '-' if v is None else ('%.*f%s' % (digits, v, unit))


def status(ok):
    return 'not measured' if ok is None else ('met' if ok else 'not met')


def table(scenes, runtime, render):
    rows = []
    d = runtime.get('default', {})
    a = runtime.get('all_cores', {})
    rate = d.get('per_source_update_hz')
    rows.append(('runtime, 32 moving sources: >= 5 IR updates per second per source',
                 '%s (default threads); %s on all cores' % (fmt(rate), fmt(a.get('per_source_update_hz'))),
                 status(None if rate is None else rate >= 5)))
    worst = d.get('worst_block_pct_of_period')
    rows.append(('runtime: worst audio block < 50 % of its period',
                 'wall %s %%, its CPU %s %%, most CPU of any block %s %%, p99 %s %%, steal %s ms' %
                 (fmt(worst, '', 1), fmt(d.get('worst_block_cpu_pct'), '', 1), fmt(d.get('max_block_cpu_pct'), '', 1),
                  fmt(d.get('p99_block_pct'), '', 1), fmt(d.get('steal_ms'), '', 0)),
                 status(None if worst is None else worst < 50)))
    rows.append(('render benchmark <= 10 s', 'median %s' % fmt(render, ' s'),
                 status(None if render is None else render <= 10)))
    worst_channel = None
    parts = []
    for name, s in sorted(scenes.items()):
        pc = s.get('per_channel')
        if pc:
            parts.append('%s: %s' % (name, ', '.join('%s %.2f' % (k, v) for k, v in sorted(pc.items()))))
            worst_channel = max([worst_channel or 0.0] + list(pc.values()))
    rows.append(('synthesis <= 3 ms per output channel (2 s IR)', '; '.join(parts) or '-',
                 status(None if worst_channel is None else worst_channel <= 3)))
    ratios = [(n, s.get('ratio')) for n, s in sorted(scenes.items())]
    known = [r for _, r in ratios if r is not None]
    rows.append(('tracer per query <= 1.3x plain Embree (best mode)',
                 ', '.join('%s %sx' % (n, fmt(r)) for n, r in ratios) or '-',
                 status(None if not known else max(known) <= 1.3)))
    parts, oks = [], []
    for name, s in sorted(scenes.items()):
        keys = ('trace_ms', 'early_ms', 'tail_ms', 'binaural_ir_ms', 'embree_ms')
        if any(s.get(k) is None for k in keys):
            parts.append('%s: -' % name)
            oks.append(None)
            continue
        update = s['trace_ms'] + s['early_ms'] + s['tail_ms'] + s['binaural_ir_ms']
        limit = 2 * s['embree_ms']
        parts.append('%s: %.1f + %.1f + %.1f + %.1f = %.1f ms against 2 x %.1f (%.2fx the Embree limit)' %
                     (name, s['trace_ms'], s['early_ms'], s['tail_ms'], s['binaural_ir_ms'], update, s['embree_ms'],
                      update / s['embree_ms']))
        oks.append(update <= limit)
    rows.append(('balanced binaural update (trace + early + tail + synthesis) <= 2x the Embree limit',
                 '; '.join(parts) or '-', status(None if not oks or None in oks else all(oks))))
    out = ['| criterion (issue 16) | measured in this run | status |', '|---|---|---|']
    out += ['| %s | %s | %s |' % r for r in rows]
    return '\n'.join(out)


def main(argv):
    if len(argv) != 2:
        sys.stderr.write('usage: bench_update_summary.py LOG (the output of tools/bench_update.sh; - for stdin)\n')
        return 2
    try:
        lines = sys.stdin.readlines() if argv[1] == '-' else open(argv[1], encoding='utf-8', errors='replace').readlines()
    except OSError as e:
        sys.stderr.write('bench_update_summary: %s: %s\n' % (argv[1], e.strerror))
        return 2
    print(table(*parse(lines)))
    return 0


if __name__ == '__main__':
    sys.exit(main(sys.argv))
