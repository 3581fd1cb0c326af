#!/usr/bin/env python3
"""How long this machine holds up a thread that does audio-like work, and
whether the thread's CPU clock counts the stall. Pure Python 3 (Linux).

The thread works in bursts (--burst ms of spinning every --period ms, as an
audio thread does a block's work), at real-time priority where allowed
(SCHED_FIFO --priority; run as root or with CAP_SYS_NICE; else it says so
and runs at normal priority). Inside a burst it reads the wall clock and
its own CPU clock back to back, so any gap between two reads is a stall:

  - a stall whose CPU time is ~0: the thread was descheduled (another
    thread of higher or equal priority ran, or the kernel);
  - a stall whose CPU time is ~its wall time: the thread was "running" but
    did not run: time a hypervisor took (steal), or an interrupt handled in
    its context. A guest's thread CPU clock counts it as the thread's own,
    so a benchmark's per-block CPU time (earshot bench runtime's
    worst_block_cpu_pct) can include it.

It prints the stalls over --min-stall ms, longest first, and the steal
/proc/stat reported over the run. Run it beside a load (e.g. `earshot bench
runtime ... --threads 2`) to see what an audio thread meets there:

    python3 tools/stall_probe.py --seconds 20
"""
import argparse
import os
import sys
import time


def steal_seconds():
    """The machine's steal time so far (all CPUs), or None."""
    try:
        with open('/proc/stat') as f:
            fields = f.readline().split()
        return int(fields[8]) / os.sysconf('SC_CLK_TCK')
    except (OSError, IndexError, ValueError):
        return None


def main():
    ap = argparse.ArgumentParser(description=__doc__.split('\n\n')[0])
    ap.add_argument('--seconds', type=float, default=20.0, help='how long to probe (default 20)')
    ap.add_argument('--burst', type=float, default=2.0, help='ms of work per period (default 2)')
    ap.add_argument('--period', type=float, default=5.0, help='ms between bursts (default 5)')
    ap.add_argument('--priority', type=int, default=70, help='SCHED_FIFO priority (default 70; 0: normal)')
    ap.add_argument('--min-stall', type=float, default=0.3, help='report stalls over this many ms (default 0.3)')
    a = ap.parse_args()
    if not (0 < a.seconds <= 3600 and 0 < a.burst < a.period <= 1000 and 0 <= a.priority <= 99 and a.min_stall > 0):
        ap.error('need 0 < seconds <= 3600, 0 < burst < period <= 1000, 0 <= priority <= 99, min-stall > 0')
    policy = 'normal'
    if a.priority > 0:
        try:
            os.sched_setscheduler(0, os.SCHED_FIFO, os.sched_param(a.priority))
            policy = 'SCHED_FIFO %d' % a.priority
        except (PermissionError, AttributeError, OSError) as e:
            policy = 'normal (SCHED_FIFO refused: %s)' % e
    steal0 = steal_seconds()
    stalls = []
    bursts = 0
    start = time.monotonic()
    next_burst = start
    while time.monotonic() - start < a.seconds:
        t = time.monotonic()
        prev_wall, prev_cpu = t, time.thread_time()
        while True:
            wall, cpu = time.monotonic(), time.thread_time()
            if wall - prev_wall > a.min_stall / 1000:
                stalls.append((wall - start, (wall - prev_wall) * 1000, (cpu - prev_cpu) * 1000))
            prev_wall, prev_cpu = wall, cpu
            if wall - t > a.burst / 1000:
                break
        bursts += 1
        next_burst += a.period / 1000
        time.sleep(max(0.0, next_burst - time.monotonic()))
    steal1 = steal_seconds()
    print('stall_probe: %d bursts of %.1f ms every %.1f ms over %.1f s at %s' %
          (bursts, a.burst, a.period, a.seconds, policy))
    counted = [s for s in stalls if s[2] > 0.5 * s[1]]
    print('stalls over %.2f ms: %d, of which %d counted as the thread\'s own CPU time' %
          (a.min_stall, len(stalls), len(counted)))
    for at, wall, cpu in sorted(stalls, key=lambda s: -s[1])[:15]:
        print('  at %7.2f s: %7.3f ms, thread CPU clock %7.3f ms%s' %
              (at, wall, cpu, '  (counted)' if cpu > 0.5 * wall else ''))
    if steal0 is not None and steal1 is not None:
        print('machine_steal_ms=%.0f (from /proc/stat, all CPUs, in %d ms ticks)' %
              ((steal1 - steal0) * 1000, 1000 // os.sysconf('SC_CLK_TCK')))
    return 0


if __name__ == '__main__':
    sys.exit(main())
