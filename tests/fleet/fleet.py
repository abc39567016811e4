#!/usr/bin/env python3
"""The fleet test bed (issue 23): N robots of two hosts each, a fleet link and top
routers, every host a real rackd in its own network namespace, on one machine.

    tests/fleet/fleet.py [--robots N] [--top-routers T] [--ci] [--json FILE]
                         [--rackd PATH] [--rackctl PATH] [--probe PATH] [--keep-logs DIR]

Topology (all namespaces and bridges are made here and deleted at exit, also on
Ctrl-C or an error; names start with rfl-<pid>-):

    robot i (1..N): rfl-P-r<i>m  main computer: system router (robot bus + fleet link),
                                 Monitor(i/0) watching the scanner at 100 Hz (robot-
                                 internal), Generator(i/1) "odometry" at 20 Hz
                    rfl-P-r<i>a  sensor computer: executor on the robot bus only,
                                 Generator(i/0) "scanner" at 100 Hz
    base station:   rfl-P-b<k>   top routers, system 0, host ids 0..T-1 (fleet link only)
                    rfl-P-ops    an operator's laptop on the fleet link (rackctl)

Each robot bus is its own bridge (br-r<i>), the fleet link another (br-f), all in a
switch namespace, so the packet counters of the fleet link's veth ports count exactly
what crosses between robots. Multicast groups: robot buses 239.255.76.67:7711, the
fleet link 239.255.76.68:7700; a system router's two interfaces each get the route of
their group.

Measured (printed, and in --json for bench/results_md.py):
  discovery   time from the first rackd's start until a listener on every robot bus
              and one on the fleet link hold every host and every component
  rpc         GET_STATUS round trips from a tool on robot 1's (and robot N's) bus: to
              the other computer of the same robot, and to both computers of every
              other robot (through two system routers and the fleet link)
  list        `rackctl list` from the operator's laptop: runs that show every
              component of every robot with its state
  idle        bytes/s and packets/s on the fleet link and on each robot bus, sent per
              host, CPU per idle host, memory (VmRSS, VmLck) of every rackd
  failover    SIGKILL of the top router that answers (robots stay reachable; the
              next one answers NOT_AVAILABLE for an unknown robot; the killed one,
              restarted, is known again), and of a system router (only its robot is
              cut off; it is reachable again after the restart)

rackd locks its memory (mlockall) as on a robot: about 42 MiB per host here (measured,
heap_prefault_mib: 4), 34 hosts in 1.4 GiB, so the test bed needs no switch to turn
locking off (a machine with less memory: lower the robots, not the locking).

--ci: the reduced form ctest runs (4 robots, fewer samples, one kill of each kind;
under a minute). Exit codes: 0 every check passed, 1 a check failed, 77 this machine
cannot run it (not root, no `ip`, no namespaces), 2 usage.
"""

import argparse
import json
import os
import re
import shutil
import signal
import subprocess
import sys
import tempfile
import threading
import time

HERE = os.path.dirname(os.path.abspath(__file__))
ROOT = os.path.dirname(os.path.dirname(HERE))

FLEET_GROUP, FLEET_PORT = "239.255.76.68", 7700
ROBOT_GROUP, ROBOT_PORT = "239.255.76.67", 7711
FLEET_URL = f"udpm://{FLEET_GROUP}:{FLEET_PORT}?ttl=1&recv_buf_size=2097152"
ROBOT_URL = f"udpm://{ROBOT_GROUP}:{ROBOT_PORT}?ttl=1&recv_buf_size=2097152"
TOOL_FLEET_URL = f"udpm://{FLEET_GROUP}:{FLEET_PORT}?ttl=1"
TOOL_ROBOT_URL = f"udpm://{ROBOT_GROUP}:{ROBOT_PORT}?ttl=1"
EXPIRY_MS = 3000
ANNOUNCE_MS = 1000

# Class ids (tims/include/rack/tims/address.h).
CLASS_GENERATOR, CLASS_MONITOR = 0x40, 0x41


def address(system, cls, instance, local=0):
    return (system << 24) | (cls << 16) | (instance << 8) | local


def die_with_parent():
    """preexec_fn: the child gets SIGKILL when this script dies, even by SIGKILL (a ctest
    timeout), so no rackd outlives a run (`ip netns exec` execs rackd in place)."""
    import ctypes
    ctypes.CDLL(None, use_errno=True).prctl(1, signal.SIGKILL)  # PR_SET_PDEATHSIG


def log(msg):
    print(f"[fleet {time.strftime('%H:%M:%S')}] {msg}", flush=True)


class Fail(Exception):
    pass


def sh(*args, check=True, timeout=30):
    r = subprocess.run(list(args), capture_output=True, text=True, timeout=timeout)
    if check and r.returncode != 0:
        raise Fail(f"'{' '.join(args)}' failed ({r.returncode}): {r.stderr.strip()}")
    return r


# ---------------------------------------------------------------- host files
def header(host, system, host_id, role):
    return (f"# fleet test bed (tests/fleet/fleet.py): {host}\n"
            f"host: {host}\nsystem: {system}\nhost_id: {host_id}\nheap_prefault_mib: 4\n"
            f"tims:\n  role: {role}\n  announce_ms: {ANNOUNCE_MS}\n  expiry_ms: {EXPIRY_MS}\n"
            f"  max_message_kib: 256\n  large_slots: 1\n  networks:\n")


def network(name, url, scope):
    return f"    - name: {name}\n      url: \"{url}\"\n      scope: {scope}\n"


def main_file(i):
    return (header(f"robot{i}-main", i, 0, "system_router") + network(f"robot{i}", ROBOT_URL, "robot") +
            network("fleet", FLEET_URL, "fleet") +
            "components:\n"
            f"  - name: r{i}-nav\n    class: Monitor\n    instance: 0\n    autostart: true\n    retry_ms: 500\n"
            "    command_task: {priority: 30}\n    data_task: {priority: 50}\n"
            f"    params: {{source: \"Generator({i}/0)\", source_period_ms: 0, silence_ms: 1000}}\n"
            f"  - name: r{i}-odometry\n    class: Generator\n    instance: 1\n    autostart: true\n"
            "    command_task: {priority: 30}\n    data_task: {priority: 55, period_ms: 50}\n"
            "    params: {amplitude: 1.0, frequency_hz: 0.2}\n")


def aux_file(i):
    return (header(f"robot{i}-aux", i, 1, "executor") + network(f"robot{i}", ROBOT_URL, "robot") +
            "components:\n"
            f"  - name: r{i}-scanner\n    class: Generator\n    instance: 0\n    autostart: true\n"
            "    command_task: {priority: 30}\n    data_task: {priority: 60, period_ms: 10}\n"
            "    params: {amplitude: 1.0, frequency_hz: 0.5}\n")


def base_file(k):
    return header(f"base-{k}", 0, k, "top_router") + network("fleet", FLEET_URL, "fleet") + "components: []\n"


# ---------------------------------------------------------------- the bed
class Bed:
    def __init__(self, args):
        self.args = args
        self.n = args.robots
        self.t = args.top_routers
        self.prefix = f"rfl-{os.getpid()}-"
        self.sw = self.prefix + "sw"
        self.made = []
        self.procs = {}  # name -> Popen
        self.files = {}  # name -> (ns, host file)
        self.dir = tempfile.mkdtemp(prefix="rack-fleet-")
        self.logs = {}

    # -- namespaces
    def ns(self, host):
        return self.prefix + host

    def add_ns(self, name):
        sh("ip", "netns", "add", name)
        self.made.append(name)
        sh("ip", "-n", name, "link", "set", "lo", "up")

    def cable(self, host, ifname, bridge, port, addr):
        ns = self.ns(host)
        sh("ip", "link", "add", ifname, "netns", ns, "type", "veth", "peer", "name", port, "netns", self.sw)
        sh("ip", "-n", self.sw, "link", "set", port, "master", bridge)
        sh("ip", "-n", self.sw, "link", "set", port, "up")
        sh("ip", "-n", ns, "addr", "add", addr, "dev", ifname)
        sh("ip", "-n", ns, "link", "set", ifname, "up")

    def build(self):
        self.add_ns(self.sw)
        for br in ["br-f"] + [f"br-r{i}" for i in range(1, self.n + 1)]:
            sh("ip", "-n", self.sw, "link", "add", br, "type", "bridge", "mcast_snooping", "0")
            sh("ip", "-n", self.sw, "link", "set", br, "up")
        for i in range(1, self.n + 1):
            for h in (f"r{i}m", f"r{i}a"):
                self.add_ns(self.ns(h))
            self.cable(f"r{i}m", "eth0", f"br-r{i}", f"r{i}m", f"10.100.{i}.1/24")
            self.cable(f"r{i}a", "eth0", f"br-r{i}", f"r{i}a", f"10.100.{i}.2/24")
            self.cable(f"r{i}m", "eth1", "br-f", f"f{i}", f"10.200.1.{i}/16")
            sh("ip", "-n", self.ns(f"r{i}a"), "route", "add", "224.0.0.0/4", "dev", "eth0")
            # The system router: the fleet group on the fleet link, every other group
            # (its robot's bus) on the robot's.
            sh("ip", "-n", self.ns(f"r{i}m"), "route", "add", "224.0.0.0/4", "dev", "eth0")
            sh("ip", "-n", self.ns(f"r{i}m"), "route", "add", f"{FLEET_GROUP}/32", "dev", "eth1")
        for k in range(self.t):
            self.add_ns(self.ns(f"b{k}"))
            self.cable(f"b{k}", "eth0", "br-f", f"fb{k}", f"10.200.0.{k + 1}/16")
            sh("ip", "-n", self.ns(f"b{k}"), "route", "add", "224.0.0.0/4", "dev", "eth0")
        self.add_ns(self.ns("ops"))
        self.cable("ops", "eth0", "br-f", "fops", "10.200.0.200/16")
        sh("ip", "-n", self.ns("ops"), "route", "add", "224.0.0.0/4", "dev", "eth0")
        for i in range(1, self.n + 1):
            self.files[f"r{i}m"] = main_file(i)
            self.files[f"r{i}a"] = aux_file(i)
        for k in range(self.t):
            self.files[f"b{k}"] = base_file(k)

    def cleanup(self):
        for name, p in list(self.procs.items()):
            if p.poll() is None:
                p.kill()
        for p in self.procs.values():
            try:
                p.wait(timeout=10)
            except subprocess.TimeoutExpired:
                pass
        for ns in reversed(self.made):
            subprocess.run(["ip", "netns", "del", ns], capture_output=True)
        self.made = []
        if self.args.keep_logs:
            os.makedirs(self.args.keep_logs, exist_ok=True)
            for f in os.listdir(self.dir):
                shutil.copy(os.path.join(self.dir, f), self.args.keep_logs)
        shutil.rmtree(self.dir, ignore_errors=True)

    # -- processes
    def start(self, host):
        path = os.path.join(self.dir, host + ".yaml")
        with open(path, "w") as f:
            f.write(self.files[host])
        logf = open(os.path.join(self.dir, host + ".log"), "ab")
        self.procs[host] = subprocess.Popen(
            ["ip", "netns", "exec", self.ns(host), self.args.rackd, path, "--crash-dir", self.dir],
            stdout=logf, stderr=subprocess.STDOUT, cwd=self.dir, preexec_fn=die_with_parent)
        logf.close()  # the child has its own descriptor

    def kill(self, host):
        p = self.procs[host]
        p.send_signal(signal.SIGKILL)
        p.wait(timeout=10)

    def hosts(self):
        return [f"b{k}" for k in range(self.t)] + [h for i in range(1, self.n + 1) for h in (f"r{i}m", f"r{i}a")]

    def ctl(self, args, ns="ops", url=TOOL_FLEET_URL, timeout=30):
        return subprocess.run(["ip", "netns", "exec", self.ns(ns), self.args.rackctl, "--lcm", url] + args,
                              capture_output=True, text=True, timeout=timeout)

    def probe(self, args, timeout=120):
        r = subprocess.run([self.args.probe] + args, capture_output=True, text=True, timeout=timeout)
        lines = [json.loads(l) for l in r.stdout.splitlines() if l.startswith("{")]
        return r, lines

    # -- counters
    def port_stats(self):
        """Bytes and packets that entered the switch from each port (what each host sent)."""
        out = {}
        r = sh("ip", "-n", self.sw, "-s", "-j", "link", "show")
        for link in json.loads(r.stdout):
            name = link.get("ifname", "")
            st = link.get("stats64", link.get("stats", {}))
            rx = st.get("rx", {})
            out[name] = (rx.get("bytes", 0), rx.get("packets", 0))
        return out

    def proc_cpu(self, pid):
        with open(f"/proc/{pid}/stat") as f:
            fields = f.read().rsplit(")", 1)[1].split()
        return (int(fields[11]) + int(fields[12])) / os.sysconf("SC_CLK_TCK")

    def proc_mem(self, pid):
        mem = {}
        with open(f"/proc/{pid}/status") as f:
            for line in f:
                if line.startswith(("VmRSS:", "VmLck:")):
                    k, v = line.split(":")
                    mem[k] = int(v.split()[0]) / 1024.0
        return mem


# ---------------------------------------------------------------- phases
def percentile(v, p):
    v = sorted(v)
    return v[min(len(v) - 1, int(p * (len(v) - 1) + 0.5))] if v else -1


def rpc_groups(bed, robot):
    """From robot `robot`'s bus: the same robot's main computer, and every other robot."""
    same = [address(robot, CLASS_GENERATOR, 1), address(robot, CLASS_MONITOR, 0)]
    other = []
    for s in range(1, bed.n + 1):
        if s != robot:
            other += [address(s, CLASS_GENERATOR, 0), address(s, CLASS_GENERATOR, 1)]
    return same, other


def reachable(bed, robot, targets_by_robot, timeout_ms=500):
    """{robot: replies} of one GET_STATUS to each target, from robot `robot`'s bus."""
    if not targets_by_robot:
        return {}
    args = ["rpc", "--ns", bed.ns(f"r{robot}a"), "--url", TOOL_ROBOT_URL, "--tool-id", str(100 + robot),
            "--count", "1", "--timeout-ms", str(timeout_ms), "--each"]
    for s, targets in targets_by_robot.items():
        args += ["--group", f"r{s}=" + ",".join(f"{t:08x}" for t in targets)]
    _, lines = bed.probe(args)
    return {int(l["group"][1:]): l["replies"] for l in lines if "group" in l}


def phase_discovery(bed, res):
    n, t = bed.n, bed.t
    want_hosts = 2 * n + t
    want_components = 3 * n
    listen = [f"{bed.ns(f'r{i}a')}={TOOL_ROBOT_URL}" for i in range(1, n + 1)] + [f"{bed.ns('ops')}={TOOL_FLEET_URL}"]
    probe = subprocess.Popen([bed.args.probe, "discover", "--listen", ",".join(listen), "--hosts", str(want_hosts),
                              "--components", str(want_components), "--timeout-s", "90"],
                             stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, preexec_fn=die_with_parent)
    time.sleep(1.0)  # the listeners are up (their own discover requests found nobody)
    t0 = time.monotonic()  # CLOCK_MONOTONIC, the probe's clock too
    for h in bed.hosts():
        bed.start(h)
    started_s = time.monotonic() - t0
    # When each rackd says it runs (its components switched on after its own 500 ms
    # of discovery warm-up; it announces them before): start-up of 34 processes on 2
    # CPUs is part of the total.
    running = {}
    while len(running) < len(bed.procs) and time.monotonic() - t0 < 90:
        for h in bed.procs:
            if h not in running:
                with open(os.path.join(bed.dir, h + ".log"), errors="replace") as f:
                    if "rackd: running" in f.read():
                        running[h] = time.monotonic() - t0
        time.sleep(0.02)
    out, err = probe.communicate(timeout=120)
    lines = [json.loads(l) for l in out.splitlines() if l.startswith("{")]
    summary = next((l for l in lines if l.get("summary") == "discover"), {})
    if not summary.get("complete"):
        raise Fail(f"discovery incomplete: {out}{err}")
    per = sorted(round(l["monotonic_ns"] / 1e6 - t0 * 1e3) for l in lines if "listener" in l)
    res["discovery"] = {
        "hosts": want_hosts, "components": want_components, "start_all_s": round(started_s, 2),
        "worst_ms": per[-1], "listeners_ms": per,
        "last_running_ms": round(1000 * max(running.values())) if len(running) == len(bed.procs) else None,
    }
    log(f"discovery: every listener ({len(per)}) knows {want_hosts} hosts and {want_components} components "
        f"{per[-1]} ms after the first rackd started (starting all took {started_s:.1f} s; the last said "
        f"'running' after {res['discovery']['last_running_ms']} ms)")
    for h, p in bed.procs.items():
        if p.poll() is not None:
            raise Fail(f"rackd {h} exited ({p.returncode})")


def phase_rpc(bed, res):
    count = bed.args.rpc_count
    res["rpc"] = {}
    for robot in sorted({1, bed.n}):
        same, other = rpc_groups(bed, robot)
        r, lines = bed.probe(["rpc", "--ns", bed.ns(f"r{robot}a"), "--url", TOOL_ROBOT_URL, "--tool-id",
                              str(100 + robot), "--count", str(count), "--group",
                              "robot=" + ",".join(f"{a:08x}" for a in same), "--group",
                              "fleet=" + ",".join(f"{a:08x}" for a in other)], timeout=600)
        by = {l["group"]: l for l in lines if "group" in l}
        if set(by) != {"robot", "fleet"}:
            raise Fail(f"rpc probe: {r.stdout}{r.stderr}")
        res["rpc"][f"from_robot{robot}"] = by
        for g in ("robot", "fleet"):
            l = by[g]
            log(f"rpc from robot {robot} ({g}, {l['targets']} targets): {l['replies']}/{l['count']} replies, "
                f"p50 {l['p50_us']:.0f} us, p99 {l['p99_us']:.0f} us, max {l['max_us']:.0f} us")
            if l["replies"] < l["count"] or l["not_ok"] != 0:
                raise Fail(f"rpc from robot {robot} to {g}: {l}")


def phase_list(bed, res):
    runs = bed.args.list_runs
    names = [f"r{i}-{c}" for i in range(1, bed.n + 1) for c in ("nav", "odometry", "scanner")]
    complete, secs, missing_any = 0, [], []
    for _ in range(runs):
        t0 = time.monotonic()
        r = bed.ctl(["list"])
        secs.append(time.monotonic() - t0)
        missing = [nm for nm in names if not re.search(rf"\b{re.escape(nm)}\b.*ENABLED", r.stdout)]
        if r.returncode == 0 and not missing and "no reply" not in r.stdout:
            complete += 1
        elif not missing_any:
            missing_any = missing or [r.stdout[-400:] + r.stderr[-400:]]
    res["list"] = {"runs": runs, "complete": complete, "components": len(names),
                   "p50_s": round(percentile(secs, 0.5), 3), "max_s": round(max(secs), 3)}
    log(f"rackctl list from the fleet link: {complete} of {runs} runs complete ({len(names)} components, "
        f"{2 * bed.n} robot hosts), p50 {percentile(secs, 0.5):.2f} s")
    if complete != runs:
        raise Fail(f"rackctl list incomplete in {runs - complete} runs; first: missing {missing_any[:5]}")


def phase_idle(bed, res):
    window = bed.args.idle_s
    pids = {h: p.pid for h, p in bed.procs.items()}
    cpu0 = {h: bed.proc_cpu(pid) for h, pid in pids.items()}
    st0 = bed.port_stats()
    t0 = time.monotonic()
    time.sleep(window)
    dt = time.monotonic() - t0
    st1 = bed.port_stats()
    cpu1 = {h: bed.proc_cpu(pid) for h, pid in pids.items()}
    rate = {k: ((st1[k][0] - st0[k][0]) / dt, (st1[k][1] - st0[k][1]) / dt) for k in st1 if k in st0}
    fleet_ports = [f"f{i}" for i in range(1, bed.n + 1)] + [f"fb{k}" for k in range(bed.t)] + ["fops"]
    fleet_bps = sum(rate[p][0] for p in fleet_ports)
    fleet_pps = sum(rate[p][1] for p in fleet_ports)
    router_pps = [rate[f"f{i}"][1] for i in range(1, bed.n + 1)]
    router_bps = [rate[f"f{i}"][0] for i in range(1, bed.n + 1)]
    bus_pps = [rate[f"r{i}m"][1] + rate[f"r{i}a"][1] for i in range(1, bed.n + 1)]
    bus_bps = [rate[f"r{i}m"][0] + rate[f"r{i}a"][0] for i in range(1, bed.n + 1)]
    aux_bps = [rate[f"r{i}a"][0] for i in range(1, bed.n + 1)]
    top_bps = [rate[f"fb{k}"][0] for k in range(bed.t)]
    cpu = {h: 100.0 * (cpu1[h] - cpu0[h]) / dt for h in pids}
    mem = {h: bed.proc_mem(pid) for h, pid in pids.items()}
    rss = sum(m.get("VmRSS", 0) for m in mem.values())
    lck = sum(m.get("VmLck", 0) for m in mem.values())
    mains = [cpu[f"r{i}m"] for i in range(1, bed.n + 1)]
    auxs = [cpu[f"r{i}a"] for i in range(1, bed.n + 1)]
    tops = [cpu[f"b{k}"] for k in range(bed.t)]
    res["idle"] = {
        "window_s": round(dt, 1),
        "fleet_link_bytes_per_s": round(fleet_bps), "fleet_link_packets_per_s": round(fleet_pps, 1),
        "system_router_to_fleet_bytes_per_s_mean": round(sum(router_bps) / len(router_bps)),
        "system_router_to_fleet_packets_per_s_max": round(max(router_pps), 1),
        "top_router_to_fleet_bytes_per_s_mean": round(sum(top_bps) / len(top_bps)),
        "robot_bus_bytes_per_s_mean": round(sum(bus_bps) / len(bus_bps)),
        "robot_bus_packets_per_s_min": round(min(bus_pps), 1),
        "aux_host_sends_bytes_per_s_mean": round(sum(aux_bps) / len(aux_bps)),
        "cpu_percent_system_router_mean": round(sum(mains) / len(mains), 2),
        "cpu_percent_aux_mean": round(sum(auxs) / len(auxs), 2),
        "cpu_percent_top_router_mean": round(sum(tops) / len(tops), 2),
        "cpu_percent_max": round(max(cpu.values()), 2),
        "rss_mib_total": round(rss, 1), "locked_mib_total": round(lck, 1),
        "rss_mib_per_host_mean": round(rss / len(mem), 1), "locked_mib_per_host_mean": round(lck / len(mem), 1),
        "rackd": len(mem),
    }
    i = res["idle"]
    log(f"idle {dt:.0f} s: fleet link {fleet_bps / 1024:.1f} KiB/s, {fleet_pps:.0f} packets/s in all; "
        f"each system router sends {i['system_router_to_fleet_bytes_per_s_mean'] / 1024:.1f} KiB/s to it "
        f"(at most {i['system_router_to_fleet_packets_per_s_max']} packets/s); each robot bus carries "
        f"{i['robot_bus_bytes_per_s_mean'] / 1024:.1f} KiB/s, at least {i['robot_bus_packets_per_s_min']:.0f} packets/s")
    log(f"CPU per host: system router {i['cpu_percent_system_router_mean']}%, sensor computer "
        f"{i['cpu_percent_aux_mean']}%, top router {i['cpu_percent_top_router_mean']}% (max {i['cpu_percent_max']}%); "
        f"memory {len(mem)} rackd: RSS {rss:.0f} MiB, locked {lck:.0f} MiB")
    # Robot-internal traffic stays home: the scanner's 100 Hz stream (and the robot's
    # GDOS) would put at least 100 packets/s per robot on the fleet link.
    if max(router_pps) >= min(bus_pps) / 10:
        raise Fail(f"a system router sends {max(router_pps):.0f} packets/s to the fleet link while its robot bus "
                   f"carries {min(bus_pps):.0f}: robot-internal traffic leaks")
    if min(bus_pps) < 100:
        raise Fail(f"a robot bus carries only {min(bus_pps):.0f} packets/s: the 100 Hz scanner stream is not flowing")


def unknown_robot_answer(bed):
    """True when someone answers NOT_AVAILABLE for a robot nobody knows (Generator(99/0))."""
    r = bed.ctl(["--timeout", "300", "--retries", "0", "status", "Generator(99/0)"], timeout=20)
    return r.returncode == 3 and "NOT_AVAILABLE" in (r.stdout + r.stderr)


def known(bed, host_name):
    r = bed.ctl(["--discover-ms", "400", "hosts"], timeout=20)
    return host_name in r.stdout


def wait_until(fn, limit_s):
    t0 = time.monotonic()
    while time.monotonic() - t0 < limit_s:
        if fn():
            return time.monotonic() - t0
        time.sleep(0.1)
    return None


def phase_failover(bed, res):
    n = bed.n
    everyone = {s: [address(s, CLASS_GENERATOR, 0), address(s, CLASS_GENERATOR, 1)] for s in range(1, n + 1)}
    res["failover"] = {"top_router": [], "system_router": []}
    if not unknown_robot_answer(bed):
        raise Fail("nobody answers NOT_AVAILABLE for an unknown robot before the kills")
    for kill in range(bed.args.kills):
        # -- the top router that answers (lowest host id alive: b0)
        victim = "b0"
        bed.kill(victim)
        t0 = time.monotonic()
        checks, lost = 0, 0
        # When base-1 answers for an unknown robot in base-0's place: asked over and over
        # beside the reachability checks (each ask takes about 0.6 s: rackctl's
        # discovery and timeout, so that is the resolution).
        took = []

        def watch_takeover():
            while time.monotonic() - t0 < 15 and not took:
                if unknown_robot_answer(bed):
                    took.append(time.monotonic() - t0)
        watcher = threading.Thread(target=watch_takeover)
        watcher.start()
        # Every robot reachable from robots 1 and N throughout the expiry time (and a
        # second more).
        while time.monotonic() - t0 < EXPIRY_MS / 1000.0 + 1.0:
            for frm in sorted({1, n}):
                got = reachable(bed, frm, {s: t for s, t in everyone.items() if s != frm})
                checks += len(got)
                lost += sum(1 for v in got.values() if v == 0)
        watcher.join()
        took_over = took[0] if took else None
        bed.start(victim)
        rejoined = wait_until(lambda: known(bed, "base-0"), 15)
        answers_after = unknown_robot_answer(bed)
        entry = {"robot_checks": checks, "robot_checks_failed": lost,
                 "other_answers_within_s": None if took_over is None else round(took_over, 2),
                 "restarted_known_after_s": None if rejoined is None else round(rejoined, 2),
                 "answers_after_restart": answers_after}
        res["failover"]["top_router"].append(entry)
        log(f"kill {kill + 1} of top router base-0: {checks - lost}/{checks} robot-to-robot checks answered "
            f"during the expiry time; unknown robot answered NOT_AVAILABLE again "
            f"(base-1) within {entry['other_answers_within_s']} s of the kill; restarted base-0 known after "
            f"{entry['restarted_known_after_s']} s")
        if lost or took_over is None or rejoined is None or not answers_after:
            raise Fail(f"top router failover: {entry}")

        # -- a system router
        victim_robot = 2 if n >= 2 else 1
        victim = f"r{victim_robot}m"
        frm = n if n != victim_robot else 1
        bed.kill(victim)
        t0 = time.monotonic()
        time.sleep(0.5)
        others = {s: t for s, t in everyone.items() if s not in (frm, victim_robot)}
        got_others = reachable(bed, frm, others)
        got_victim = reachable(bed, frm, {victim_robot: [address(victim_robot, CLASS_GENERATOR, 0)]})
        bed.start(victim)
        back = wait_until(lambda: reachable(bed, frm, {victim_robot: everyone[victim_robot]}).get(victim_robot, 0) == 2, 20)
        entry = {"other_robots_reachable": sum(1 for v in got_others.values() if v > 0), "other_robots": len(others),
                 "its_sensor_computer_reachable_while_down": got_victim.get(victim_robot, 0) > 0,
                 "reachable_after_restart_s": None if back is None else round(back, 2)}
        res["failover"]["system_router"].append(entry)
        log(f"kill {kill + 1} of robot {victim_robot}'s system router: {entry['other_robots_reachable']}/"
            f"{entry['other_robots']} other robots reachable from robot {frm}, its sensor computer "
            f"{'REACHABLE' if entry['its_sensor_computer_reachable_while_down'] else 'cut off'}; after the restart "
            f"reachable again in {entry['reachable_after_restart_s']} s")
        if (entry["other_robots_reachable"] != len(others) or entry["its_sensor_computer_reachable_while_down"]
                or back is None):
            raise Fail(f"system router failover: {entry}")


def markdown(res):
    """The results as a Markdown table (bench/RESULTS.md; results_md.py renders it)."""
    rows = []
    d, i = res.get("discovery"), res.get("idle")
    if d:
        rows.append(("every host knows every host and component (listeners on each robot bus and the fleet link)",
                     f"{d['worst_ms']} ms after the first rackd started ({d['hosts']} hosts, {d['components']} "
                     f"components; listeners {d['listeners_ms'][0]}..{d['listeners_ms'][-1]} ms; the last rackd "
                     f"said 'running' after {d['last_running_ms']} ms)"))
    for frm, by in res.get("rpc", {}).items():
        for g, label in (("robot", "within the robot (other computer)"), ("fleet", "across the fleet (every other robot)")):
            l = by[g]
            rows.append((f"GET_STATUS round trip {frm.replace('_', ' ')}, {label}",
                         f"p50 {l['p50_us']:.0f} us, p99 {l['p99_us']:.0f} us, max {l['max_us']:.0f} us "
                         f"({l['replies']}/{l['count']} replies, {l['targets']} targets)"))
    if res.get("list"):
        l = res["list"]
        rows.append(("`rackctl list` from the fleet link complete",
                     f"{l['complete']} of {l['runs']} runs ({l['components']} components; p50 {l['p50_s']} s a run)"))
    if i:
        rows += [
            ("fleet link, all senders", f"{i['fleet_link_bytes_per_s'] / 1024:.1f} KiB/s, "
                                        f"{i['fleet_link_packets_per_s']:.0f} packets/s"),
            ("sent to the fleet link per system router (announcements of its robot's hosts)",
             f"{i['system_router_to_fleet_bytes_per_s_mean'] / 1024:.2f} KiB/s, at most "
             f"{i['system_router_to_fleet_packets_per_s_max']} packets/s"),
            ("sent to the fleet link per top router", f"{i['top_router_to_fleet_bytes_per_s_mean'] / 1024:.2f} KiB/s"),
            ("robot bus (100 Hz scanner stream, 20 Hz odometry, GDOS, announcements of the fleet)",
             f"{i['robot_bus_bytes_per_s_mean'] / 1024:.1f} KiB/s, at least {i['robot_bus_packets_per_s_min']:.0f} packets/s"),
            ("CPU per idle host: system router / sensor computer / top router",
             f"{i['cpu_percent_system_router_mean']}% / {i['cpu_percent_aux_mean']}% / "
             f"{i['cpu_percent_top_router_mean']}% of one CPU (max {i['cpu_percent_max']}%)"),
            ("memory of the fleet", f"{i['rackd']} rackd: VmRSS {i['rss_mib_total']:.0f} MiB, locked "
                                    f"{i['locked_mib_total']:.0f} MiB ({i['locked_mib_per_host_mean']} MiB a host)"),
        ]
    f = res.get("failover", {})
    for k, e in enumerate(f.get("top_router", [])):
        rows.append((f"kill {k + 1} of the answering top router (SIGKILL)",
                     f"{e['robot_checks'] - e['robot_checks_failed']}/{e['robot_checks']} robot-to-robot checks "
                     f"answered during the expiry; the other answers for unknown robots within "
                     f"{e['other_answers_within_s']} s; restarted one known after {e['restarted_known_after_s']} s"))
    for k, e in enumerate(f.get("system_router", [])):
        rows.append((f"kill {k + 1} of robot 2's system router (SIGKILL)",
                     f"{e['other_robots_reachable']}/{e['other_robots']} other robots reachable, robot 2 "
                     f"{'REACHABLE' if e['its_sensor_computer_reachable_while_down'] else 'cut off'}; reachable "
                     f"{e['reachable_after_restart_s']} s after its restart"))
    out = ["| measured | figure |", "|---|---|"] + [f"| {a} | {b} |" for a, b in rows]
    return "\n".join(out) + "\n"


def unsupported():
    if os.geteuid() != 0:
        return "the fleet test bed needs root (network namespaces)"
    if shutil.which("ip") is None:
        return "the fleet test bed needs iproute2's ip"
    probe = f"rfl-{os.getpid()}-probe"
    r = subprocess.run(["ip", "netns", "add", probe], capture_output=True, text=True)
    if r.returncode != 0:
        return "network namespaces are not available here: " + r.stderr.strip()
    subprocess.run(["ip", "netns", "del", probe], capture_output=True)
    return None


def delete_stale():
    """Namespaces of earlier runs whose process is gone (a run killed before its cleanup)."""
    r = subprocess.run(["ip", "netns", "list"], capture_output=True, text=True)
    for line in r.stdout.splitlines():
        name = line.split()[0] if line.split() else ""
        m = re.match(r"rfl-(\d+)-", name)
        if m and not os.path.exists(f"/proc/{m.group(1)}"):
            subprocess.run(["ip", "netns", "del", name], capture_output=True)


def main():
    build = os.path.join(ROOT, "build")
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--robots", type=int, default=16)
    ap.add_argument("--top-routers", type=int, default=2)
    ap.add_argument("--ci", action="store_true", help="the reduced form: fewer samples, one kill of each kind")
    ap.add_argument("--rpc-count", type=int, help="round trips per group and robot (default 1000; --ci 100)")
    ap.add_argument("--list-runs", type=int, help="rackctl list runs (default 100; --ci 5)")
    ap.add_argument("--kills", type=int, help="kills of each kind (default 3; --ci 1)")
    ap.add_argument("--idle-s", type=float, help="idle measurement window (default 20; --ci 5)")
    ap.add_argument("--json", help="write the results here")
    ap.add_argument("--rackd", default=os.path.join(build, "tools", "rackd"))
    ap.add_argument("--rackctl", default=os.path.join(build, "tools", "rackctl"))
    ap.add_argument("--probe", default=os.path.join(build, "tests", "fleet", "fleet_probe"))
    ap.add_argument("--keep-logs", help="copy every rackd's log and host file here at the end")
    args = ap.parse_args()
    if args.robots < 2 or args.robots > 100 or args.top_routers < 1 or args.top_routers > 9:
        ap.error("--robots 2..100 (a fleet), --top-routers 1..9")
    args.rpc_count = args.rpc_count or (100 if args.ci else 1000)
    args.list_runs = args.list_runs or (5 if args.ci else 100)
    args.kills = args.kills if args.kills is not None else (1 if args.ci else 3)
    args.idle_s = args.idle_s or (5 if args.ci else 20)
    for p in (args.rackd, args.rackctl, args.probe):
        if not os.access(p, os.X_OK):
            ap.error(f"{p} is not an executable (build rackd, rackctl and fleet_probe)")
    why = unsupported()
    if why:
        print(f"fleet.py: SKIPPED: {why}", flush=True)
        return 77
    delete_stale()
    bed = Bed(args)

    def on_signal(sig, _frame):
        raise KeyboardInterrupt(f"signal {sig}")

    signal.signal(signal.SIGTERM, on_signal)
    res = {"robots": args.robots, "top_routers": args.top_routers, "hosts": 2 * args.robots + args.top_routers,
           "load_before": os.getloadavg(), "started": time.strftime("%Y-%m-%dT%H:%M:%SZ", time.gmtime())}
    rc = 0
    t0 = time.monotonic()
    try:
        log(f"{args.robots} robots x 2 hosts + {args.top_routers} top routers in network namespaces "
            f"(load average {os.getloadavg()[0]:.2f})")
        bed.build()
        phase_discovery(bed, res)
        phase_idle(bed, res)
        phase_rpc(bed, res)
        phase_list(bed, res)
        phase_failover(bed, res)
        for h, p in bed.procs.items():
            if p.poll() is not None:
                raise Fail(f"rackd {h} exited ({p.returncode})")
        log("every check passed")
    except Fail as e:
        log(f"FAILED: {e}")
        res["failed"] = str(e)
        rc = 1
    except KeyboardInterrupt as e:
        log(f"interrupted ({e})")
        rc = 1
    finally:
        res["load_after"] = os.getloadavg()
        res["duration_s"] = round(time.monotonic() - t0, 1)
        if rc != 0:
            for h in bed.procs:
                path = os.path.join(bed.dir, h + ".log")
                if os.path.exists(path):
                    with open(path, errors="replace") as f:
                        tail = f.read()[-1500:]
                    if "error" in tail.lower() or bed.procs[h].poll() is not None:
                        print(f"--- {h} (last lines)\n{tail}", flush=True)
        bed.cleanup()
    res["title"] = f"Fleet test bed: {args.robots} robots x 2 hosts, {args.top_routers} top routers (issue 23)"
    res["about"] = ("Every host a real rackd in its own network namespace; a robot bus per robot, one fleet link "
                    "(separate bridges, so the fleet link's veth counters count what crosses), a system router per "
                    "robot, top routers on the base station (tests/fleet/fleet.py).")
    res["markdown"] = markdown(res)
    res["notes"] = [f"load average {res['load_before'][0]:.2f} before, {res['load_after'][0]:.2f} after "
                    f"({os.cpu_count()} CPUs); {res['duration_s']} s"] + ([f"FAILED: {res['failed']}"] if "failed" in res else [])
    print(res["markdown"], flush=True)
    if args.json:
        with open(args.json, "w") as f:
            json.dump(res, f, indent=1)
    log(f"done in {res['duration_s']} s (load average {res['load_after'][0]:.2f})")
    return rc


if __name__ == "__main__":
    sys.exit(main())
