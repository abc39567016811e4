#!/usr/bin/env python3
"""Footprint of rackd (issue 19 item 2): memory locked (VmLck: the size of the locked
mappings, as the kernel counts it; and the locked pages resident, the sum of smaps'
Locked:), resident (VmRSS),
shared objects mapped and the time from exec to every autostart component ENABLED
(rackd says "running" once start() has switched each one on and it answered), for
each host file, for this build's rackd and for a reference rackd (today's layout:
every class linked in, built from main in another build tree), alternating the two
over rounds, beside cyclictest -m (the RT reference: a locked process that does
nothing but wake up).

    bench/footprint.py --rackd BUILD/tools/rackd [--before OTHER/tools/rackd
                       [--before-root OTHER_SOURCE_TREE]]
                       [--rounds N] [--configs configs/demo.yaml,configs/sim_mcl.yaml]
                       --json OUT

--configs: host files, comma-separated. A relative one is looked up in the source tree
the rackd runs from (this one; --before-root for the reference), then in that tree's
configs/, then from the current directory; an absolute one is taken as given. So
`demo.yaml`, `configs/demo.yaml` and the path of any host file all work, and the
reference runs its own tree's file of that name.

Needs root (mlockall, SCHED_FIFO); runs each rackd on its own LCM port (ttl=0).
Where the locked memory goes is broken down from /proc/PID/smaps for the first
round of each case: the heap (and its pre-fault reserve), thread stacks, the
mapped libraries, anonymous mappings (glibc arenas, rings)."""

import argparse
import json
import os
import re
import signal
import statistics
import subprocess
import sys
import time

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))


def status_kb(pid, key):
    with open(f"/proc/{pid}/status") as f:
        for line in f:
            if line.startswith(key + ":"):
                return int(line.split()[1])
    return None


def shared_objects(pid):
    libs = set()
    with open(f"/proc/{pid}/maps") as f:
        for line in f:
            parts = line.split(None, 5)
            if len(parts) == 6 and re.search(r"\.so(\.|$)", parts[5].strip()):
                libs.add(parts[5].strip())
    return len(libs)


def locked_breakdown(pid):
    """Locked kB by kind of mapping, from /proc/PID/smaps."""
    kinds = {}
    cur = None
    with open(f"/proc/{pid}/smaps") as f:
        for line in f:
            m = re.match(r"^[0-9a-f]+-[0-9a-f]+ \S+ \S+ \S+ \S+\s*(.*)$", line)
            if m:
                name = m.group(1).strip()
                if name == "[heap]":
                    cur = "heap ([heap], incl. the pre-fault reserve)"
                elif name.startswith("[stack"):
                    cur = "main stack"
                elif re.search(r"\.so(\.|$)", name) or name.endswith("rackd") or name.endswith("cyclictest"):
                    cur = "libraries and the executable"
                elif name == "":
                    cur = "anonymous (thread stacks, glibc arenas, rings, mmap'd allocations)"
                else:
                    cur = "other (" + name.split("/")[-1] + ")"
                continue
            if line.startswith("Locked:") and cur:
                kinds[cur] = kinds.get(cur, 0) + int(line.split()[1])
    return {k: v for k, v in sorted(kinds.items(), key=lambda kv: -kv[1]) if v > 0}


def threads(pid):
    return len(os.listdir(f"/proc/{pid}/task"))


def resolve_config(config, root):
    """The host file `config` names for a rackd of source tree `root`: an absolute path as
    given; a relative one in `root`, else in root/configs/, else from the current directory."""
    tried = []
    for cand in ([config] if os.path.isabs(config) else
                 [os.path.join(root, config), os.path.join(root, "configs", config), os.path.abspath(config)]):
        if cand in tried:
            continue
        tried.append(cand)
        if os.path.isfile(cand):
            return cand
    raise SystemExit(f"footprint.py: no host file '{config}' (tried {', '.join(tried)})")


def run_rackd(rackd, config, port, settle_s, breakdown, root=ROOT):
    url = f"udpm://239.255.76.67:{port}?ttl=0"
    t0 = time.monotonic()
    p = subprocess.Popen([rackd, config, "--lcm", url], cwd=root, stdout=subprocess.DEVNULL,
                         stderr=subprocess.PIPE, text=True)
    enabled = None
    err = []
    try:
        deadline = t0 + 30
        for line in p.stderr:
            err.append(line)
            if "rackd: running" in line:
                enabled = time.monotonic() - t0
                break
            if time.monotonic() > deadline:
                break
        if enabled is None:
            p.kill()
            p.wait()
            sys.stderr.write("".join(err[-20:]))
            raise RuntimeError(f"{rackd} {config}: never said 'running'")
        time.sleep(settle_s)
        r = {"time_to_enabled_s": enabled, "vmlck_kb": status_kb(p.pid, "VmLck"), "vmrss_kb": status_kb(p.pid, "VmRSS"),
             "shared_objects": shared_objects(p.pid), "threads": threads(p.pid)}
        kinds = locked_breakdown(p.pid)
        r["locked_resident_kb"] = sum(kinds.values())
        if breakdown:
            r["locked_by_kind_kb"] = kinds
        return r
    finally:
        if p.poll() is None:
            p.send_signal(signal.SIGTERM)
            try:
                p.wait(timeout=10)
            except subprocess.TimeoutExpired:
                p.kill()
                p.wait()
        # drain the rest of stderr
        try:
            p.stderr.read()
        except Exception:
            pass


def run_cyclictest(settle_s, breakdown):
    p = subprocess.Popen(["cyclictest", "-m", "-q", "-t1", "-p80", "-i1000", "-D", str(int(settle_s + 3))],
                         stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    try:
        time.sleep(settle_s)
        r = {"vmlck_kb": status_kb(p.pid, "VmLck"), "vmrss_kb": status_kb(p.pid, "VmRSS"),
             "shared_objects": shared_objects(p.pid), "threads": threads(p.pid)}
        kinds = locked_breakdown(p.pid)
        r["locked_resident_kb"] = sum(kinds.values())
        if breakdown:
            r["locked_by_kind_kb"] = kinds
        return r
    finally:
        p.send_signal(signal.SIGINT)
        p.wait()


def summary(samples, key):
    vals = [s[key] for s in samples if s.get(key) is not None]
    if not vals:
        return None
    return {"median": statistics.median(vals), "min": min(vals), "max": max(vals), "n": len(vals)}


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--rackd", required=True)
    ap.add_argument("--before", help="the reference rackd (today's layout)")
    ap.add_argument("--before-root", help="the source tree whose configs/ the reference runs (default: this one)")
    ap.add_argument("--rounds", type=int, default=3)
    ap.add_argument("--configs", default="configs/demo.yaml,configs/sim_mcl.yaml",
                    help="host files, comma-separated: a path, or a name in the tree's configs/ "
                         "(demo.yaml); default %(default)s")
    ap.add_argument("--settle", type=float, default=1.0, help="seconds after 'running' before reading /proc")
    ap.add_argument("--json", required=True)
    a = ap.parse_args()

    layouts = [("plug-ins", os.path.abspath(a.rackd), ROOT)]
    if a.before:
        layouts.append(("before", os.path.abspath(a.before), os.path.abspath(a.before_root or ROOT)))
    configs = [c for c in a.configs.split(",") if c]
    # Every host file found before anything runs (a typo fails at once, not after rounds).
    for _, _, root in layouts:
        for cfg in configs:
            resolve_config(cfg, root)
    samples = {}  # (layout, config) -> [sample]
    port = 7720
    for r in range(a.rounds):
        order = layouts if r % 2 == 0 else list(reversed(layouts))
        for name, rackd, root in order:
            for cfg in configs:
                port += 1
                s = run_rackd(rackd, resolve_config(cfg, root), port, a.settle, breakdown=(r == 0), root=root)
                samples.setdefault((name, cfg), []).append(s)
                print(f"round {r + 1} {name:8} {cfg:22} VmLck {s['vmlck_kb'] / 1024:7.1f} MiB  "
                      f"VmRSS {s['vmrss_kb'] / 1024:7.1f} MiB  {s['shared_objects']:3} .so  "
                      f"ENABLED after {s['time_to_enabled_s']:.3f} s", flush=True)
        s = run_cyclictest(a.settle, breakdown=(r == 0))
        samples.setdefault(("cyclictest -m", ""), []).append(s)
        print(f"round {r + 1} cyclictest -m VmLck {s['vmlck_kb'] / 1024:.1f} MiB (resident locked "
              f"{s['locked_resident_kb'] / 1024:.1f} MiB)  {s['shared_objects']} .so", flush=True)

    out = {"title": "rackd footprint: locked memory, shared objects, time to ENABLED", "cases": []}
    for (name, cfg), ss in samples.items():
        case = {"layout": name, "config": cfg, "rounds": len(ss)}
        for key in ("vmlck_kb", "locked_resident_kb", "vmrss_kb", "shared_objects", "threads", "time_to_enabled_s"):
            case[key] = summary(ss, key)
        case["locked_by_kind_kb"] = ss[0].get("locked_by_kind_kb", {})
        out["cases"].append(case)
    with open(a.json, "w") as f:
        json.dump(out, f, indent=1)


if __name__ == "__main__":
    main()
