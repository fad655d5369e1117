#!/usr/bin/env python3
"""Read a run's outputs into DataFrames and plot them.

Runs `cosim run short-hop --out DIR` (unless DIR already holds a run), reads
summary.json, trajectory.csv, power.csv and the three motor models' CSVs
with crazyflie_cosim.outputs, prints a few numbers and writes DIR/python.png:
altitude, battery current and SOC over time, and the three models' motor
power (thesis Figures 5.5-5.6).

    python examples/python/read_outputs.py [DIR]     (default out/short-hop)
"""

import subprocess
import sys
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt
from crazyflie_cosim.outputs import OutputError, Run
from crazyflie_cosim.server import WorldServerError, find_checkout


def main():
    out = Path(sys.argv[1] if len(sys.argv) > 1 else "out/short-hop")
    if not (out / "summary.json").is_file():
        root = find_checkout()
        if root is None:
            raise OutputError(
                f"{out} holds no run and the checkout (for cosim) is not around the working directory"
            )
        cosim = root / "target" / "release" / "cosim"
        subprocess.run([str(cosim), "run", "short-hop", "--out", str(out)], check=True)
    run = Run(out)
    s = run.summary
    traj, power = run.trajectory(), run.power()
    motors = {m: run.motors(m) for m in ("empirical", "dandrea", "stolaroff")}
    print(f"{out}: completed {s['completed']}, {s['targets_reached']}/{s['targets_total']} targets, "
          f"world time {s['world_time_s']} s, SOC at the end {s['battery']['soc_end']:.4f}")  # fmt: skip
    print(f"trajectory: {len(traj)} rows, highest {traj['z'].max():.3f} m; "
          f"power: {len(power)} rows, mean battery current {power['i_battery_a'].mean():.3f} A")  # fmt: skip
    for m, df in motors.items():
        # power_w in 1 ms rows: the energy is the sum times 1 ms.
        print(
            f"  motor model {m:9s}: {df['power_w'].sum() * 1e-3:8.2f} J (summary: {s['energy_j'][m]:.2f} J)"
        )

    fig, ax = plt.subplots(3, 1, figsize=(8, 8), sharex=True)
    ax[0].plot(traj["time_ms"] / 1000, traj["z"])
    ax[0].set_ylabel("altitude (m)")
    ax[0].set_title("trajectory.csv")
    ax[1].plot(
        power["time_s"], power["i_battery_a"], lw=0.6, label="battery current (A)"
    )
    ax[1].set_ylabel("current (A)")
    ax2 = ax[1].twinx()
    ax2.plot(power["time_s"], power["soc"] * 100, color="tab:red", label="SOC (%)")
    ax2.set_ylabel("SOC (%)", color="tab:red")
    for m, df in motors.items():
        ax[2].plot(df["time_s"], df["power_w"], lw=0.6, label=m)
    ax[2].set_ylabel("motor power (W)")
    ax[2].set_xlabel(
        "time (s): altitude on the world clock, currents and power on the platform clock"
    )
    ax[2].legend()
    fig.suptitle(f"{out.name}: read with crazyflie_cosim.outputs")
    fig.tight_layout()
    fig.savefig(out / "python.png", dpi=90)
    print("plot", out / "python.png")


if __name__ == "__main__":
    try:
        main()
    except (OutputError, WorldServerError, subprocess.CalledProcessError, OSError) as e:
        sys.exit(f"read_outputs.py: {e}")
