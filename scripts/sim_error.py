#!/usr/bin/env python3
"""Localisation error of a running simulation (configs/sim_nav.yaml, sim_mcl.yaml)
against the simulated truth, through rackctl.

Every interval it reads the chassis' newest sample (its truth_x/y/phi) and the
Position estimate AT THAT SAMPLE'S TIME (`rackctl get-data position --time T`), so
the two refer to the same moment; with an MCL component it also compares MCL's
estimate with the truth at the time of the scan it was made from. At the end (or on
Ctrl-C) it prints RMS, median, p95 and maximum.

    scripts/sim_error.py                         # 60 samples, one every 0.5 s
    scripts/sim_error.py --samples 0             # until Ctrl-C
    scripts/sim_error.py --lcm 'udpm://239.255.76.67:7667?ttl=0' --rackctl build/tools/rackctl

Exit codes: 0 ok, 1 no sample could be compared (rackd not running, no chassis
truth), 2 usage.
"""
import argparse
import json
import math
import os
import subprocess
import sys
import time


def main():
    here = os.path.dirname(os.path.abspath(__file__))
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--lcm", default=os.environ.get("LCM_DEFAULT_URL", ""), help="TiMS/LCM network (rackctl's default when empty)")
    ap.add_argument("--rackctl", default=os.path.join(here, "..", "build", "tools", "rackctl"))
    ap.add_argument("--samples", type=int, default=60, help="how many (0: until Ctrl-C)")
    ap.add_argument("--interval", type=float, default=0.5, help="seconds between samples")
    ap.add_argument("--chassis", default="chassis")
    ap.add_argument("--position", default="position")
    ap.add_argument("--mcl", default="mcl", help="MCL component name ('' to skip)")
    ap.add_argument("--quiet", action="store_true", help="only the summary")
    args = ap.parse_args()
    base = [args.rackctl] + (["--lcm", args.lcm] if args.lcm else [])

    def get(name, t=None):
        cmd = base + ["get-data", name] + (["--time", str(t)] if t else [])
        r = subprocess.run(cmd, capture_output=True, text=True, timeout=30)
        if r.returncode != 0:
            return None
        try:
            return json.loads(r.stdout)
        except json.JSONDecodeError:
            return None

    pos_err, mcl_err = [], []
    use_mcl = bool(args.mcl)
    i = 0
    try:
        while args.samples == 0 or i < args.samples:
            i += 1
            c = get(args.chassis)
            if not c or not c["data"].get("truth_valid"):
                print(f"sim_error: no truth from '{args.chassis}'", file=sys.stderr)
                time.sleep(args.interval)
                continue
            t, truth = c["time_ns"], c["data"]
            line = f"truth ({truth['truth_x']:7.3f}, {truth['truth_y']:7.3f})"
            p = get(args.position, t)
            if p:
                e = math.hypot(truth["truth_x"] - p["data"]["x"], truth["truth_y"] - p["data"]["y"])
                pos_err.append(e)
                line += f"  position error {e:6.3f} m"
            if use_mcl:
                m = get(args.mcl)
                if m is None:
                    use_mcl = False  # no MCL in this host
                elif m["data"].get("scan_time_ns"):
                    ct = get(args.chassis, m["data"]["scan_time_ns"])
                    if ct:
                        e = math.hypot(ct["data"]["truth_x"] - m["data"]["x"], ct["data"]["truth_y"] - m["data"]["y"])
                        mcl_err.append(e)
                        line += f"  mcl error {e:6.3f} m"
            if not args.quiet:
                print(line, flush=True)
            time.sleep(args.interval)
    except KeyboardInterrupt:
        pass

    def summary(name, errs):
        if not errs:
            return
        s = sorted(errs)
        rms = math.sqrt(sum(e * e for e in s) / len(s))
        print(f"{name}: {len(s)} samples, error vs truth RMS {rms:.3f} m, median {s[len(s) // 2]:.3f}, "
              f"p95 {s[min(len(s) - 1, int(len(s) * 0.95))]:.3f}, max {s[-1]:.3f}")

    summary("position", pos_err)
    summary("mcl", mcl_err)
    return 0 if pos_err else 1


if __name__ == "__main__":
    sys.exit(main())
