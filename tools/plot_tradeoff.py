#!/usr/bin/env python3
"""Plot the CSV of `earshot tradeoff`: error (JND, log y) against compute time
(s, log x), one line per metric plus the worst metric (max). A grid CSV has
points labelled rays x bounces, one line style per bounce limit; a --presets
CSV (a `preset` column first) has one point per preset, labelled with its name.
Usage: plot_tradeoff.py IN.csv OUT.svg

Exit codes: 0 ok, 2 an error (one line on stderr). The SVG is written to a
temporary file in the same folder and renamed, so a failure leaves no partial
plot behind."""
import csv
import math
import os
import sys
import tempfile

METRICS = [("edt_jnd", "EDT"), ("t20_jnd", "T20"), ("t30_jnd", "T30"), ("c50_jnd", "C50"),
           ("c80_jnd", "C80"), ("d50_jnd", "D50"), ("ts_jnd", "Ts")]
COLUMNS = ["rays", "bounces", "seconds_median"] + [m for m, _ in METRICS] + ["max_jnd"]
FLOOR = 1e-3  # log axes cannot show 0 JND; such points sit on this floor


def fail(message):
    print("plot_tradeoff: error: " + message, file=sys.stderr)
    sys.exit(2)


def main():
    if len(sys.argv) != 3:
        fail("usage: plot_tradeoff.py IN.csv OUT.svg")
    src, dst = sys.argv[1], sys.argv[2]
    try:
        import matplotlib
        matplotlib.use("Agg")
        import matplotlib.pyplot as plt
    except ImportError:
        fail("matplotlib is not installed (Debian: apt-get install python3-matplotlib)")
    try:
        with open(src, newline="") as f:
            reader = csv.DictReader(f)
            presets = reader.fieldnames == ["preset"] + COLUMNS
            if reader.fieldnames != COLUMNS and not presets:
                fail(f"{src}: header is {reader.fieldnames}, expected {COLUMNS} or {['preset'] + COLUMNS}")
            rows = [{k: (v if k == "preset" else float(v)) for k, v in r.items()} for r in reader]
    except (OSError, ValueError) as e:
        fail(f"{src}: {e}")
    if not rows:
        fail(f"{src}: no data rows")
    # One line per metric and bounce limit, joining the ray counts in order:
    # colour = metric, line style and marker = bounce limit.
    from matplotlib.lines import Line2D
    styles = [("-", "o"), ("--", "s"), (":", "^"), ("-.", "D")]
    # A preset CSV is drawn as one group (one line per metric through the
    # presets in order of cost); a grid CSV as one group per bounce limit.
    bounce_values = [None] if presets else sorted({int(r["bounces"]) for r in rows})
    colors = plt.rcParams["axes.prop_cycle"].by_key()["color"]
    fig, ax = plt.subplots(figsize=(10, 6.5))

    def y_of(value):
        return max(value, FLOOR) if math.isfinite(value) else float("nan")

    xs_all = []
    for bi, b in enumerate(bounce_values):
        group = sorted((r for r in rows if b is None or int(r["bounces"]) == b),
                       key=lambda r: r["seconds_median"] if b is None else r["rays"])
        ls, mk = styles[bi % len(styles)]
        xs = [max(r["seconds_median"], 1e-6) for r in group]
        xs_all += xs
        for mi, (key, _) in enumerate(METRICS):
            ax.plot(xs, [y_of(r[key]) for r in group], linestyle=ls, marker=mk, markersize=3, linewidth=1,
                    alpha=0.7, color=colors[mi % len(colors)])
        ys = [y_of(r["max_jnd"]) for r in group]
        ax.plot(xs, ys, linestyle=ls, marker=mk, markersize=6, linewidth=2.2, color="black")
        for x, y, r in zip(xs, ys, group):
            label = r["preset"] if presets else f"{int(r['rays'])}x{int(r['bounces'])}"
            ax.annotate(label, (x, y), textcoords="offset points", xytext=(4, 4), fontsize=7)
    handles = [Line2D([], [], color=colors[mi % len(colors)], label=name) for mi, (_, name) in enumerate(METRICS)]
    handles.append(Line2D([], [], color="black", linewidth=2.2, label="max (worst metric)"))
    for bi, b in enumerate(bounce_values if not presets else []):
        ls, mk = styles[bi % len(styles)]
        handles.append(Line2D([], [], color="grey", linestyle=ls, marker=mk, label=f"{b} bounces"))
    ax.legend(handles=handles, fontsize=8, loc="upper left", bbox_to_anchor=(1.01, 1.0))
    xs = sorted(xs_all)
    ax.axhline(1.0, color="grey", linestyle="--", linewidth=1)
    ax.text(xs[0], 1.05, "1 JND", color="grey", fontsize=8)
    ax.set_xscale("log")
    ax.set_yscale("log")
    ax.margins(x=0.08)  # room for the labels of the rightmost points
    from matplotlib.ticker import FormatStrFormatter
    ax.xaxis.set_minor_formatter(FormatStrFormatter("%g"))  # a sweep often spans less than a decade
    ax.yaxis.set_minor_formatter(FormatStrFormatter("%g"))  # a preset run often spans less than a decade
    ax.tick_params(axis="both", which="minor", labelsize=7)
    ax.set_xlabel("wall time per IR, median (s)")
    ax.set_ylabel("error vs reference: mean |JND| over 250 Hz - 4 kHz")
    points = "quality presets" if presets else "rays x bounces"
    ax.set_title(f"earshot tradeoff: {os.path.basename(src)} (points: {points})")
    ax.grid(True, which="both", alpha=0.3)
    fig.tight_layout()

    folder = os.path.dirname(os.path.abspath(dst))
    fd, tmp = tempfile.mkstemp(prefix=".tradeoff_", suffix=".svg", dir=folder)
    os.close(fd)
    try:
        # A fixed hash salt and no date keep the SVG the same for the same CSV.
        plt.rcParams["svg.hashsalt"] = "earshot"
        fig.savefig(tmp, format="svg", metadata={"Date": None})
        umask = os.umask(0)
        os.umask(umask)
        os.chmod(tmp, 0o666 & ~umask)  # mkstemp makes it 0600; give it a normal file's mode
        os.replace(tmp, dst)
    except OSError as e:
        os.unlink(tmp)
        fail(f"{dst}: {e}")
    except BaseException:  # Ctrl-C (KeyboardInterrupt) too: no temporary file left
        os.unlink(tmp)
        raise


if __name__ == "__main__":
    main()
