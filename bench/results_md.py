#!/usr/bin/env python3
"""Writes bench/RESULTS.md (to stdout) from the JSON results of bench_rpc and
bench_jitter and the environment bench/run recorded. Called by bench/run."""

import argparse
import json
import os
import re
import sys


# Loads bench_jitter runs under, in this order; bench/run writes jitter-<key>.json.
JITTER_LOADS = [("idle", "idle"), ("stress", "under stress-ng"), ("mcl", "with MCL running at lower priority")]

# Everything after this line in RESULTS.md is kept when bench/run rewrites the file:
# sections of benchmarks that bench/run does not run yet (their commands are in them).
KEEP_MARKER = ("<!-- bench/run writes everything above this line; the sections below come from "
               "other benchmarks and are kept as they are -->")


def plot_jitter(jitters, folder):
    """PNG histograms (log counts) of both sides per load; {} when matplotlib is missing."""
    try:
        import matplotlib
        matplotlib.use("Agg")
        import matplotlib.pyplot as plt
    except ImportError:
        sys.stderr.write("results_md.py: matplotlib missing (apt-get install python3-matplotlib): no plots\n")
        return {}
    os.makedirs(folder, exist_ok=True)
    out = {}
    for key, label, j in jitters:
        fig, ax = plt.subplots(figsize=(7, 3.6), dpi=100)
        for side, name, colour in (("rack", "RACK-RT data task", "tab:blue"),
                                   ("cyclictest", "cyclictest", "tab:orange")):
            h = j["sides"][side]["histogram_us"]
            if not h:
                continue
            xs = [b for b, _ in h]
            ys = [c for _, c in h]
            ax.step(xs, ys, where="post", label=f"{name} (p99 {j['sides'][side]['latency']['p99_ns'] / 1000:.0f} us)",
                    color=colour)
        ax.set_yscale("log")
        ax.set_xscale("log")
        ax.set_xlabel("wake-up latency (us)")
        ax.set_ylabel("cycles")
        ax.set_title(f"1 kHz periodic task, SCHED_FIFO {j['priority']}, CPU {j['cpu']}: {label}")
        ax.grid(True, which="both", alpha=0.3)
        ax.legend()
        fig.tight_layout()
        path = os.path.join(folder, f"jitter-{key}.png")
        fig.savefig(path)
        plt.close(fig)
        out[key] = path
    return out


def load_env(path):
    env = {}
    with open(path) as f:
        for line in f:
            key, _, value = line.rstrip("\n").partition("=")
            env[key] = value
    return env


def us(ns):
    return "–" if ns is None else f"{ns / 1000.0:.1f}"


def us2(ns):
    return "–" if ns is None else f"{ns / 1000.0:.2f}"


def verdict(ratio, target):
    if ratio is None:
        return "no data"
    if ratio <= target:
        return f"**met** ({ratio:.2f}x <= {target:.2f}x)"
    return f"**MISSED** by {100.0 * (ratio / target - 1.0):.0f}% ({ratio:.2f}x > {target:.2f}x)"


def strace_calls(path):
    """{"futex:FUTEX_OP": n, "clock_nanosleep": n} from `strace -f -e trace=... -o` output:
    each call counted once, at its start line."""
    calls = {}
    if not os.path.exists(path):
        return calls
    with open(path) as f:
        for line in f:
            if "resumed>" in line:
                continue
            m = re.search(r"\bfutex\(0x[0-9a-f]+, ([A-Z_|]+)", line)
            if m:
                op = m.group(1).split("|")[0].replace("_PRIVATE", "")
                calls["futex:" + op] = calls.get("futex:" + op, 0) + 1
                calls["futex"] = calls.get("futex", 0) + 1
            elif re.search(r"\bclock_nanosleep\(", line):
                calls["clock_nanosleep"] = calls.get("clock_nanosleep", 0) + 1
    return calls


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--results", required=True)
    ap.add_argument("--rpc-cmd", required=True)
    ap.add_argument("--root", required=True)
    ap.add_argument("--keep-tail", help="an existing RESULTS.md whose part after the KEEP marker is kept")
    ap.add_argument("--plots", help="folder for PNG plots (matplotlib); relative links from RESULTS.md")
    a = ap.parse_args()

    env = load_env(os.path.join(a.results, "env.txt"))
    with open(os.path.join(a.results, "rpc.json")) as f:
        rpc = json.load(f)
    jitters = []  # (key, label, results), idle first
    for key, label in JITTER_LOADS:
        path = os.path.join(a.results, f"jitter-{key}.json")
        if os.path.exists(path):
            with open(path) as f:
                jitters.append((key, label, json.load(f)))
    if not jitters:
        sys.exit("results_md.py: no jitter-*.json results")
    jit = jitters[0][2]
    root = a.root.rstrip("/") + "/"
    rpc_cmd = a.rpc_cmd.replace(root, "")
    plots = plot_jitter(jitters, a.plots) if a.plots else {}
    plot_rel = os.path.relpath(a.plots, os.path.join(a.root, "bench")) if a.plots else ""
    mode = env.get("mode", "?")
    preempt_rt = env.get("preempt_rt", "0").strip() == "1"

    out = []
    w = out.append
    w("# RACK-RT benchmarks: results")
    w("")
    w(f"Written by `bench/run --{mode}` on {env.get('date', '?')}, commit {env.get('commit', '?')}. "
      "Each benchmark runs its reference in the same run, same binary or same invocation, "
      "with the same placement and priority (STYLE.md 11). Raw JSON and logs: "
      "`<build-dir>/bench/results/`. Regenerate with `bench/run --quick` (about 1 minute) "
      "or `bench/run` (full, a few minutes).")
    w("")
    w("## Machine and load")
    w("")
    w(f"- Kernel: `{env.get('uname', '?')}`")
    w(f"- PREEMPT_RT: **{'yes' if preempt_rt else 'no'}**"
      + ("" if preempt_rt else
         " (a stock PREEMPT_DYNAMIC kernel in a VM: absolute latencies are not those of an RT "
         "system; the ratios against the reference measured beside them are what count)."))
    w(f"- CPU: {env.get('cpu_model', '?')}, {env.get('nproc', '?')} online CPUs, cpuidle driver "
      f"`{env.get('cpuidle', '?')}`, clocksource `{env.get('clocksource', '?')}`, "
      f"RT throttling `sched_rt_runtime_us/period` = {env.get('rt_runtime', '?')}")
    w(f"- {env.get('cyclictest', 'cyclictest ?')}")
    w(f"- Load average (1/5/15 min): at start {env.get('load_start', '?')}; after bench_rpc "
      f"{env.get('load_rpc_after', '?')}; after bench_jitter {env.get('load_jitter_after', '?')}. "
      "The benchmarks' own threads count towards it (they are runnable part of the time).")
    busy_s = env.get("busy_start", "").strip()
    busy_e = env.get("busy_end", "").strip()
    w(f"- Other processes above 5% CPU (lifetime average, from ps) at start: {busy_s or 'none'}; "
      f"at the end: {busy_e or 'none'}. Other builds and tests share this 2-CPU VM; outliers "
      "(p99.9, max) move with them from run to run, medians much less.")
    w("")

    # ---- summary ----------------------------------------------------------------
    w("## Summary")
    w("")
    w("| benchmark | placement | RACK-RT | reference | ratio | target |")
    w("|---|---|---|---|---|---|")
    for m in rpc["modes"]:
        mech = m["mechanisms"]
        r = mech.get("rack_rpc", {}).get("latency", {})
        f = mech.get("futex", {}).get("latency", {})
        place = (f"same CPU ({m['server_cpu']})" if m["mode"] == "same"
                 else f"cross CPU (client {m['client_cpu']}, server {m['server_cpu']})")
        w(f"| RPC round trip, median | {place} | {us2(r.get('p50_ns'))} us | "
          f"{us2(f.get('p50_ns'))} us (futex ping-pong) | {m['ratio_p50']:.2f}x | "
          f"{verdict(m['ratio_p50'], rpc['target_ratio_p50'])} |")
    for key, label, j in jitters:
        rk = j["sides"]["rack"]["latency"]
        ct = j["sides"]["cyclictest"]["latency"]
        w(f"| 1 kHz wake-up latency, p99, {label} | CPU {j['cpu']}, SCHED_FIFO {j['priority']} | "
          f"{us(rk['p99_ns'])} us | {us(ct['p99_ns'])} us (cyclictest, same load) | {j['ratio_p99']:.2f}x | "
          f"{verdict(j['ratio_p99'], j['target_ratio_p99'])} |")
    w("")

    # ---- rpc ------------------------------------------------------------------------
    w("## 1. bench_rpc: RPC round trip inside one executor vs a raw ping-pong")
    w("")
    w("A client thread (SCHED_FIFO, same priority as the command task) calls "
      "`tims::Endpoint::call(GET_STATUS)` on a Generator's command task in a `rack::Executor` "
      "(`lcm: false`, memory policy applied) and waits for the reply in its own mailbox; "
      "each round trip is timed with `clock_gettime(CLOCK_MONOTONIC)`. The reference is two "
      "SCHED_FIFO threads of the same priority in the same binary handing a ball back and forth "
      "through one **futex** word (`FUTEX_WAIT/FUTEX_WAKE_PRIVATE`, no spinning). Two diagnostic "
      "ping-pongs show where the difference comes from: `PI mutex+condvar` (two channels of "
      "PI mutex + `rt::PiCondVar` + flag: the primitives a TiMS mailbox is built from, without TiMS) and "
      "`PI mutex+futex` (the same channels, the reader sleeping on a bare futex word). The mechanisms run in alternating blocks; between round trips the "
      f"client sleeps {rpc['gap_us']} us (so the CPU is never 100% busy with RT threads, which "
      "would trigger RT throttling); each block starts with "
      f"{rpc['warmup']} untimed round trips. SCHED_FIFO priority {rpc['priority']}; "
      f"{rpc['iterations']} timed round trips per mechanism and placement in {rpc['rounds']} blocks; "
      f"PM QoS {'held at 0' if rpc['pm_qos_hold'] else 'left at the system default'}.")
    w("")
    labels = {"futex": "raw futex ping-pong (reference)", "rack_rpc": "**RACK-RT GET_STATUS RPC**",
              "pi_condvar": "diag: PI mutex + condvar", "pi_futex": "diag: PI mutex + futex word"}
    for m in rpc["modes"]:
        if m["mode"] == "same":
            w(f"### Same CPU: client and server pinned to CPU {m['server_cpu']}")
        else:
            w(f"### Across CPUs: client on CPU {m['client_cpu']}, server on CPU {m['server_cpu']}")
        w("")
        w("| mechanism | min | p50 | p90 | p99 | p99.9 | max | vs futex p50 |")
        w("|---|---|---|---|---|---|---|---|")
        base = m["mechanisms"].get("futex", {}).get("latency", {}).get("p50_ns")
        for key in ("futex", "rack_rpc", "pi_condvar", "pi_futex"):
            if key not in m["mechanisms"]:
                continue
            lat = m["mechanisms"][key]["latency"]
            rel = f"{lat['p50_ns'] / base:.2f}x" if base else "–"
            w(f"| {labels[key]} | {us2(lat['min_ns'])} | {us2(lat['p50_ns'])} | {us2(lat['p90_ns'])} | "
              f"{us2(lat['p99_ns'])} | {us2(lat['p999_ns'])} | {us2(lat['max_ns'])} | {rel} |")
        w("")
        w(f"All figures in us. Ratio RACK-RT / futex: **p50 {m['ratio_p50']:.2f}x** "
          f"(target <= {rpc['target_ratio_p50']:.1f}x: {verdict(m['ratio_p50'], rpc['target_ratio_p50'])}), "
          f"p99 {m['ratio_p99']:.2f}x.")
        w("")

    calls = {k: strace_calls(os.path.join(a.results, f"strace-{k}.txt"))
             for k in ("futex", "rack", "pi_condvar", "pi_futex")}
    if any(calls.values()):
        w("**System calls per round trip** (same CPU, 2000 round trips under "
          "`strace -f -e trace=futex,clock_nanosleep`; thread start/stop adds a few):")
        w("")
        w("| mechanism | futex calls / round trip | FUTEX_WAIT(_BITSET) | FUTEX_WAKE | FUTEX_UNLOCK_PI | FUTEX_LOCK_PI | clock_nanosleep (the gap) |")
        w("|---|---|---|---|---|---|---|")
        for key, label in (("futex", "raw futex ping-pong"), ("rack", "RACK-RT RPC"),
                           ("pi_condvar", "PI mutex + condvar"), ("pi_futex", "PI mutex + futex word")):
            c = calls.get(key, {})
            if not c:
                continue
            n = 2000.0
            wait = c.get("futex:FUTEX_WAIT", 0) + c.get("futex:FUTEX_WAIT_BITSET", 0)
            w(f"| {label} | {c.get('futex', 0) / n:.2f} | {wait / n:.2f} | {c.get('futex:FUTEX_WAKE', 0) / n:.2f} | "
              f"{c.get('futex:FUTEX_UNLOCK_PI', 0) / n:.2f} | {c.get('futex:FUTEX_LOCK_PI', 0) / n:.2f} | "
              f"{c.get('clock_nanosleep', 0) / n:.2f} |")
        w("")

    # ---- jitter -----------------------------------------------------------------
    w("## 2. bench_jitter: 1 kHz periodic data task vs cyclictest")
    w("")
    w(f"RACK-RT side: a host with one Generator, `period_ms: {jit['interval_us'] / 1000:g}`, data task "
      f"SCHED_FIFO {jit['priority']} pinned to CPU {jit['cpu']} (command task pinned there too, idle), "
      "`lcm: false`, switched on, memory policy applied as rackd does; after the run its data "
      "task's latency histogram is read (`DataComponentBase::data_task_stats()`). Reference: "
      f"`cyclictest -m -p {jit['priority']} -i {jit['interval_us']} -a {jit['cpu']} -t1 -D <s>s -q -h 10000` "
      "(rt-tests 2.x has no `-n`; `clock_nanosleep` is its default). Both measure wake-up time minus "
      "deadline on CLOCK_MONOTONIC after an absolute `clock_nanosleep`, in 1-us buckets, and both skip "
      "missed periods; percentiles of both come from the same code and are truncated to whole us, "
      f"as cyclictest prints them. {jit['seconds']} s per side in {jit['rounds']} round(s), run one after "
      "the other (alternating order), never concurrently. /dev/cpu_dma_latency "
      + ("was held at 0 for both sides (cyclictest does that by default; rackd does not)."
         if jit["pm_qos_hold"] else "was left alone for both sides (cyclictest `--default-system`)."))
    w("")
    for jkey, label, jit in jitters:
        w(f"### Load: {label}")
        w("")
        if jit.get("load_cmd"):
            w(f"Background load for both sides, started 2 s before and stopped after the measurement: "
              f"`{jit['load_cmd'].replace(root, '')}` (normal scheduling).")
            w("")
        w("| side | samples | min | p50 | p90 | p99 | p99.9 | max | mean |")
        w("|---|---|---|---|---|---|---|---|---|")
        for key, side_label in (("rack", "**RACK-RT data task**"), ("cyclictest", "cyclictest (reference)")):
            lat = jit["sides"][key]["latency"]
            w(f"| {side_label} | {lat['samples']} | {us(lat['min_ns'])} | {us(lat['p50_ns'])} | {us(lat['p90_ns'])} | "
              f"{us(lat['p99_ns'])} | {us(lat['p999_ns'])} | {us(lat['max_ns'])} | {us(lat['mean_ns'])} |")
        w("")
        w(f"All figures in us. Ratio RACK-RT / cyclictest: **p99 {jit['ratio_p99']:.2f}x** "
          f"(target <= {jit['target_ratio_p99']:.1f}x: {verdict(jit['ratio_p99'], jit['target_ratio_p99'])}), "
          f"p50 {jit['ratio_p50']:.2f}x. RACK-RT missed periods: {jit['sides']['rack']['overruns']}; "
          f"cyclictest histogram overflows (>= 10 ms): {jit['sides']['cyclictest']['histogram_overflows']}.")
        w("")
        edges = [0, 10, 20, 30, 50, 100, 200, 500, 1000, 10000]
        hists = {k: dict((b, c) for b, c in jit["sides"][k]["histogram_us"]) for k in ("rack", "cyclictest")}
        w("Histogram (counts per latency range, us):")
        w("")
        w("| range | " + " | ".join(
            f"[{edges[i]}, {edges[i + 1]})" if i + 2 < len(edges) else f">= {edges[i]}"
            for i in range(len(edges) - 1)) + " |")
        w("|---|" + "---|" * (len(edges) - 1))
        for k, side_label in (("rack", "RACK-RT"), ("cyclictest", "cyclictest")):
            row = []
            for i in range(len(edges) - 1):
                row.append(str(sum(c for b, c in hists[k].items() if edges[i] <= b < edges[i + 1])))
            w(f"| {side_label} | " + " | ".join(row) + " |")
        w("")
        if jkey in plots:
            w(f"![wake-up latency histogram, {label}]({plot_rel}/{os.path.basename(plots[jkey])})")
            w("")

    # ---- analysis -----------------------------------------------------------------
    w("## Notes: where RACK-RT is slower, and why")
    w("")
    for m in rpc["modes"]:
        mech = m["mechanisms"]
        f50 = mech.get("futex", {}).get("latency", {}).get("p50_ns")
        r50 = mech.get("rack_rpc", {}).get("latency", {}).get("p50_ns")
        c50 = mech.get("pi_condvar", {}).get("latency", {}).get("p50_ns")
        p50 = mech.get("pi_futex", {}).get("latency", {}).get("p50_ns")
        if None in (f50, r50):
            continue
        line = (f"- RPC, {m['mode']} CPU: RACK-RT's median is {us2(r50 - f50)} us "
                f"({100.0 * (r50 / f50 - 1.0):+.0f}%) from the raw futex ping-pong")
        if c50 is not None and p50 is not None:
            line += (f"; the bare mailbox primitives (PI mutex + rt::PiCondVar) account for "
                     f"{us2(c50 - f50)} us of it, TiMS itself (router look-up, header, two lock/unlock "
                     f"pairs per send, copies, deadline clock reads) for {us2(r50 - c50)} us; the same channels "
                     f"with a futex word instead of the condvar take {us2(p50)} us ({p50 / f50:.2f}x futex)")
        w(line + ".")
    w("- **Condition variable**: a TiMS mailbox is a PI mutex plus `rt::PiCondVar`. That condvar was "
      "glibc's `pthread_cond_t` until 2026-11-22; after `pthread_cond_wait` glibc re-acquires a PI mutex "
      "with `FUTEX_WAITERS` forced on (`__pthread_mutex_cond_lock`), so the next unlock of every mailbox "
      "was a `FUTEX_UNLOCK_PI` system call even with nobody waiting, and the same-CPU median was 1.71x "
      "the raw ping-pong on this machine. `rt::PiCondVar` is now a futex sequence word (waiters counted, "
      "no system call for a notify nobody waits for); the `PI mutex + condvar` row measures it"
      + (f": strace counted {calls['rack'].get('futex', 0) / 2000.0:.1f} futex calls per RACK-RT round trip "
         f"({calls['rack'].get('futex:FUTEX_UNLOCK_PI', 0) / 2000.0:.1f} of them FUTEX_UNLOCK_PI) against "
         f"{calls['futex'].get('futex', 0) / 2000.0:.1f} for the raw ping-pong"
         if calls.get("rack") and calls.get("futex") else "")
      + ".")
    w("- Every `Endpoint::call` waits with a deadline (`pthread_cond_timedwait`, an hrtimer armed and "
      "cancelled per call) and reads CLOCK_MONOTONIC three more times; the raw ping-pong waits without "
      "a timeout. Small next to the system calls.")
    w("- **Idle jitter** is the least repeatable figure on this VM: on 2026-11-22 the same build measured "
      "idle p99 ratios from 0.71x to 2.56x in 10-15 s runs (cyclictest's own idle p99 moved between 22 and "
      "31 us, and rare wake-ups of 0.5-1 ms land on either side). The runs under stress-ng and beside MCL, "
      "where the vCPU never enters its haltpoll idle loop, are steadier. For a figure to rely on, run the "
      "full `bench/run` (60 s per side in 2 alternating rounds) on a quiet machine.")
    w("- **Across CPUs** the figures are dominated by waking a halted virtual CPU (an IPI through the "
      "hypervisor, then the guest's haltpoll exit): every mechanism pays it twice per round trip, "
      "so ratios there are close to 1 and the spread (p99, max) follows the other load on the "
      "VM more than the mechanism.")
    w("- **Periodic task**: the executor's data task is the same loop as cyclictest's "
      "(`clock_nanosleep(TIMER_ABSTIME)` on CLOCK_MONOTONIC, latency recorded right after), plus "
      "`loop()` (Generator: a sine, a ring write, no listeners) and a few relaxed counter updates after "
      "the measurement; so the two distributions should match within the run-to-run noise of a shared "
      "VM, which is what the ratio shows. The floor of about 10 us and medians of tens of us are the "
      "VM's timer path, not either program. cyclictest holds `/dev/cpu_dma_latency` at 0 by default; "
      "rackd does not, so a rackd without it would see slower wake-ups from idle than here (this "
      "benchmark holds it for both sides unless `--no-pm-qos`). Holding it belongs in the "
      "executor's start-up policy (core/rt), next to mlockall.")
    w("")

    w("## Exact commands")
    w("")
    w("```")
    w(f"bench/run --{mode}")
    w(f"{rpc_cmd}")
    for _, _, j in jitters:
        w(j.get("command", "bench_jitter ?").replace(root, ""))
    w("# inside bench_jitter, per segment:")
    w(f"cyclictest -m -p {jit['priority']} -i {jit['interval_us']} -a {jit['cpu']} -t1 -D <seconds>s -q -h 10000"
      + ("" if jit["pm_qos_hold"] else " --default-system"))
    if any(calls.values()):
        w("# syscall counts:")
        w("strace -f -e trace=futex,clock_nanosleep -o strace-M.txt <build-dir>/bench/bench_rpc --cpu-mode same "
          "--iterations 2000 --rounds 1 --warmup 0 --gap-us 100 --only M   # M: futex rack pi_condvar pi_futex")
    w("```")
    w("")
    w(KEEP_MARKER)
    tail = ""
    if a.keep_tail and os.path.exists(a.keep_tail):
        with open(a.keep_tail) as f:
            text = f.read()
        if KEEP_MARKER in text:
            tail = text.split(KEEP_MARKER, 1)[1].lstrip("\n")
    sys.stdout.write("\n".join(out) + "\n" + tail)


if __name__ == "__main__":
    main()
