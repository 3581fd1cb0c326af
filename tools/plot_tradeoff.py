#!/usr/bin/env python3
"""Plot the CSV of `earshot tradeoff`: error (JND, log y) against compute time
(s, log x), one line per metric plus the worst metric (max), points labelled
rays x bounces. Usage: plot_tradeoff.py IN.csv OUT.svg

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
            if reader.fieldnames != COLUMNS:
                fail(f"{src}: header is {reader.fieldnames}, expected {COLUMNS}")
            rows = [{k: float(v) for k, v in r.items()} for r in reader]
    except (OSError, ValueError) as e:
        fail(f"{src}: {e}")
    if not rows:
        fail(f"{src}: no data rows")
    rows.sort(key=lambda r: r["seconds_median"])

    fig, ax = plt.subplots(figsize=(9, 6))
    xs = [max(r["seconds_median"], 1e-6) for r in rows]
    for key, name in METRICS:
        ys = [max(r[key], FLOOR) if math.isfinite(r[key]) else float("nan") for r in rows]
        ax.plot(xs, ys, marker="o", markersize=3, linewidth=1, alpha=0.8, label=name)
    ys = [max(r["max_jnd"], FLOOR) for r in rows]
    ax.plot(xs, ys, marker="s", color="black", linewidth=2, label="max (worst metric)")
    for x, y, r in zip(xs, ys, rows):
        ax.annotate(f"{int(r['rays'])}x{int(r['bounces'])}", (x, y), textcoords="offset points",
                    xytext=(4, 4), fontsize=7)
    ax.axhline(1.0, color="grey", linestyle="--", linewidth=1)
    ax.text(xs[0], 1.05, "1 JND", color="grey", fontsize=8)
    ax.set_xscale("log")
    ax.set_yscale("log")
    ax.set_xlabel("wall time per IR, median (s)")
    ax.set_ylabel("error vs reference: mean |JND| over 250 Hz - 4 kHz")
    ax.set_title(f"earshot tradeoff: {os.path.basename(src)} (points: rays x bounces)")
    ax.grid(True, which="both", alpha=0.3)
    ax.legend(fontsize=8)
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


if __name__ == "__main__":
    main()
