#!/usr/bin/env python3
"""When a hovering drone could no longer hold its height (docs/COSIM.md,
"Hover until the battery cannot hold it"): for each run directory, the first
world time below 0.8 m after it reached 0.95 m (trajectory.csv), and the SOC
and terminal voltage at the matching platform time (power.csv; world time
scaled by the run's platform/world time ratio, the thesis sync's drift).

    scripts/hover_sink.py out/hover-endurance out/hover-endurance-sweep/run-*
"""
import csv
import json
import os
import sys


def sink(run):
    traj = os.path.join(run, "trajectory.csv")
    reached, t_sink, t_last = False, None, 0.0
    with open(traj) as f:
        for r in csv.DictReader(f):
            if r.get("z") is None:  # a run cut mid-row
                break
            t_last = float(r["time_ms"]) / 1000
            z = float(r["z"])
            reached = reached or z > 0.95
            if reached and z < 0.8 and t_sink is None:
                t_sink = t_last
    with open(os.path.join(run, "power.csv")) as f:
        power = list(csv.DictReader(f))
    p_end = float(power[-1]["time_s"])
    summary = os.path.join(run, "summary.json")
    w_end = t_last
    if os.path.exists(summary):
        with open(summary) as f:
            s = json.load(f)
        w_end = s.get("world_time_s") or w_end
        p_end = s.get("platform_time_s") or p_end
    if t_sink is None:
        return f"{run}: held its height to the end (world {w_end:.1f} s)"
    p = t_sink * p_end / w_end
    row = next((r for r in power if float(r["time_s"]) >= p), power[-1])
    return (
        f"{run}: below 0.8 m at world {t_sink:.3f} s (platform ~{p:.1f} s), "
        f"SOC {100 * float(row['soc']):.2f} %, terminal {float(row['v_battery_v']):.2f} V; "
        f"power.csv ends at platform {float(power[-1]['time_s']):.1f} s, "
        f"SOC {100 * float(power[-1]['soc']):.2f} %"
    )


if __name__ == "__main__":
    if len(sys.argv) < 2:
        sys.exit("usage: hover_sink.py RUN_DIR...")
    for run in sys.argv[1:]:
        try:
            print(sink(run))
        except (OSError, KeyError, ValueError, IndexError) as e:
            print(f"{run}: cannot read: {e}", file=sys.stderr)
            sys.exit(1)
