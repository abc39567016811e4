#!/usr/bin/env python3
"""Writes the seed corpora of the fuzz harnesses (tests/fuzz/corpus/<name>/seed_*).

The seeds are committed; run this again only to change them (it rewrites the seed_*
files and leaves every other file, such as inputs a fuzzer found, alone). Each seed is
a well-formed input of its decoder, laid out as its harness reads it
(tests/fuzz/fuzz_<name>.cpp says how), so the fuzzer starts from the valid paths.
"""
import os
import struct

HERE = os.path.dirname(os.path.abspath(__file__))


def write(name, seeds):
    folder = os.path.join(HERE, "corpus", name)
    os.makedirs(folder, exist_ok=True)
    for f in os.listdir(folder):
        if f.startswith("seed_"):
            os.remove(os.path.join(folder, f))
    for i, data in enumerate(seeds):
        with open(os.path.join(folder, "seed_%02d" % i), "wb") as f:
            f.write(data)


def tims_header(little, type_, prio, seq, dest, src, body, body_le=True):
    flags = (1 if little else 0) | (2 if body_le else 0)
    e = "<" if little else ">"
    return struct.pack(e + "BbBBIII", flags, type_, prio, seq, dest, src, 16 + len(body)) + body


def lcm_string(s):
    b = s.encode() + b"\0"
    return struct.pack(">i", len(b)) + b


# TiMS header: requests and replies in both byte orders, empty and with a body.
write("tims_header", [
    tims_header(True, 3, 0, 1, 0x01110100, 0x01010102, b""),
    tims_header(False, 6, 5, 2, 0x01110100, 0x01010102, struct.pack(">qI4x", 100000000, 0x01010103), False),
    tims_header(True, -6, 0, 7, 0x01010103, 0x01110100, bytes(32)),
    tims_header(True, 0, 0, 1, 0, 0, b"")[:12],
])

# Payloads: byte 0 type index, byte 1 mode (bit 0: other byte order; bits 1-2: 0 decode,
# 1 set_field_from_text, 2 class tables), then the body or field index + text.
payload = []
for t in (0, 1, 5, 7, 8, 9, 14, 21, 34, 39):
    payload.append(bytes([t, 0]) + bytes(range(1, 97)))
    payload.append(bytes([t, 1]) + bytes(range(97, 1, -1)))
payload.append(bytes([5, 0]) + b"the reason\0")  # ErrorText
payload.append(bytes([7, 2, 0]) + b"speed")       # ParamRecord.name
payload.append(bytes([7, 2, 4]) + b"-42")         # ParamRecord.int_value
payload.append(bytes([22, 2, 3]) + b"1.5,2,3.25") # PathMake.x
payload.append(bytes([0x40, 4]) + bytes(24))      # Generator through the class table
payload.append(bytes([0x11, 5]) + bytes(64))      # Ladar, other byte order
write("payload", payload)

# LCM types: byte 0 type (0 tims_packet, 1 component_info, 2 host_announce,
# 3 discover_request, 4 gdos_record, 5 gdos_batch, 6 gdos_listener); bit 7 clear: the
# harness puts the fingerprint in front.
component = struct.pack(">i", 0x01400100) + lcm_string("gen") + lcm_string("Generator")
announce = (struct.pack(">iqqbbqq", 1, 1234, 0, 0, 0, 5, 1000000000) + lcm_string("host-a")
            + struct.pack(">iiii", 1, 2, 4242, 0x01010200) + component)
discover = struct.pack(">qqbq", 1234, 0, 0, 5) + lcm_string("rackctl")
record = struct.pack(">qqi", 5, 1, 0x01400100) + lcm_string("gen") + struct.pack(">bi", 3, 0) + lcm_string("hello")
batch = struct.pack(">q", 5) + lcm_string("host-a") + struct.pack(">ii", 4242, 2) + record + record
packet = struct.pack(">qqiiiiibbi", 1234, 0, 1, 1, 16, 16, 0, 0, 0, 16) + tims_header(False, 3, 0, 1, 1, 2, b"")
listener = struct.pack(">q", 5) + lcm_string("gdos") + struct.pack(">i", 99)
write("lcm_gen", [bytes([0]) + packet, bytes([1]) + component, bytes([2]) + announce, bytes([3]) + discover,
                    bytes([4]) + record, bytes([5]) + batch, bytes([6]) + listener])

# NMEA: byte 0 piece size; the textbook sentences (gpsd's documentation).
nmea = (b"$GPGGA,123519,4807.038,N,01131.000,E,1,08,0.9,545.4,M,46.9,M,,*47\r\n"
        b"$GPRMC,123519,A,4807.038,N,01131.000,E,022.4,084.4,230394,003.1,W*6A\r\n"
        b"$GPGSA,A,3,04,05,,09,12,,,24,,,,,2.5,1.3,2.1*39\r\n"
        b"$GPVTG,054.7,T,034.4,M,005.5,N,010.2,K*48\r\n")
write("nmea", [bytes([63]) + nmea, bytes([6]) + nmea[:140], bytes([0]) + b"$GPGGA,123520,,,,,0,00,,,M,,M,,*" ])


# SCIP: byte 0 piece size; a PP answer and an MD scan.
def scip_sum(s):
    return bytes([(sum(s) & 0x3F) + 0x30])


def scip_line(s):
    return s + scip_sum(s) + b"\n"


def enc3(v):
    return bytes([((v >> 12) & 0x3F) + 0x30, ((v >> 6) & 0x3F) + 0x30, (v & 0x3F) + 0x30])


pp = b"PP\n" + scip_line(b"00")
for kv in (b"DMIN:20", b"DMAX:5600", b"ARES:1024", b"AMIN:44", b"AMAX:725", b"AFRT:384", b"SCAN:600"):
    pp += kv + b";" + scip_sum(kv) + b"\n"
pp += b"\n"
data = b"".join(enc3(1000 + i) for i in range(30))
scan = (b"MD0100012901000\n" + scip_line(b"99") + scip_line(b"0000") + scip_line(data[:64]) + scip_line(data[64:])
        + b"\n")
write("scip", [bytes([255]) + pp + scan, bytes([49]) + scan, bytes([3]) + pp])

# CoLa-A: byte 0 piece size; an LMS111 scan telegram (as tests/drivers/protocol_test.cpp).
body = (b"sSN LMDscandata 1 1 89A27F 0 0 343 347 277B3F9 277F7EC 0 0 0 0 0 1388 168 0 1 DIST1 3F800000 00000000 "
        b"FFF92230 1388 5 3E8 7D0 BB8 0 FA0 0 0 0 0 0 0")
rssi = body.replace(b"0 1 DIST1", b"0 2 DIST1").replace(b"0 FA0 0", b"0 FA0 RSSI1 3F800000 00000000 FFF92230 1388 5 1 2 3 4 5 0")
write("cola", [bytes([255]) + b"\x02" + body + b"\x03", bytes([16]) + b"\x02" + rssi + b"\x03",
               bytes([255]) + b"\x02sRA LMDscandata 1\x03noise\x02sEA LMDscandata 1\x03"])


# CANopen: byte 0 node-1, byte 1 mode, byte 2 filter count, then (length, bytes) packets.
def can_frame(can_id, data):
    return struct.pack("<IB3x", can_id, len(data)) + data.ljust(8, b"\0")


def packets(frames):
    return b"".join(bytes([len(f)]) + f for f in frames)


node = 5
frames = [can_frame(0x700 + node, b"\x05"), can_frame(0x180 + node, struct.pack("<ii", 100, -2000)),
          can_frame(0x280 + node, struct.pack("<H", 0x0627)), can_frame(0x580 + node, b"\x4b\x41\x60\x00\x27\x06\0\0"),
          can_frame(0x20000004, bytes([0, 0x30, 0, 0, 0, 0, 0, 0]))]
write("canopen", [bytes([node - 1, 0, 0]) + packets(frames),
                  bytes([node - 1, 1, 1]) + struct.pack("<II", 0x580 + node, 0x7FF) + packets(frames),
                  bytes([node - 1, 2, 0]) + packets([can_frame(0x580 + node, b"\x60\x40\x60\x00\0\0\0\0")] * 3
                                                    + [can_frame(0x580 + node, b"\x4b\x41\x60\x00\x27\x00\0\0")]),
                  bytes([node - 1, 0, 0]) + packets([b"\x01\x02\x03", can_frame(0x123, b"")[:12]])])

# Access: byte 0 bit 0 clear: texts; set: rules and messages.
write("access", [b"\0Ladar(0/1)", b"\0Ladar(1/2)#3", b"\0*(1/*)", b"\0Class0x90(*/*)#2", b"\x000x10000000/0xff000000",
                 b"\0get_status", b"\0-21",
                 bytes([1, 1, 16, 1, 0]) + struct.pack("<II", 0xFFFFFF00, 0x01400100) + bytes([0, 0x1F, 3, 3, 4, 5])
                 + struct.pack("<H", 10) + bytes([2])
                 + b"".join(struct.pack("<bBIIHB", 3, 0, 0x01400100, 0x02010100, 0, i) for i in range(6))])

# Link authentication: byte 0 mode (0 key file, 1 received packet, 2 signed here), byte 1 channel.
key = b"000102030405060708090a0b0c0d0e0f101112131415161718191a1b1c1d1e1f"
write("link_auth", [b"\0\0# a key\n" + key + b"\n",
                    b"\0\0" + key + b"\n" + key[::-1] + b"\n\n",
                    b"\1\0" + bytes(40) + b"RKA1" + bytes(44),
                    b"\2\1" + b"".join(bytes([1]) + struct.pack("<H", s) + bytes([0, 8]) + b"payload!" for s in (1, 2, 2, 70))])

# Class description (rack/core/class_description.h): byte 0 even: one encoded
# description; odd: CLASS reply bodies, each a 2-byte length and the body.
def cd_str(s):
    b = s.encode()
    return struct.pack("<H", len(b)) + b


def cd_type(name, size, fields):
    out = cd_str(name) + struct.pack("<IH", size, len(fields))
    for fname, kind, offset, count in fields:
        out += cd_str(fname) + struct.pack("<BII", kind, offset, count)
    return out


def cd_param(name, kind, flags, unit, lo, hi, default, doc, choices=()):
    out = cd_str(name) + struct.pack("<BB", kind, flags) + cd_str(unit) + struct.pack("<dd", lo, hi)
    out += cd_str(default) + cd_str(doc) + bytes([len(choices)]) + b"".join(cd_str(c) for c in choices)
    return out


inf = float("inf")
counter = (b"RKCD" + bytes([1, 0x91, 0, 0]) + cd_str("Counter") + cd_str("Counter") + cd_str("test: counts")
           + b"\1" + cd_type("CounterData", 24, [("count", 8, 0, 1), ("rate", 11, 8, 1), ("label", 3, 16, 8)])
           + struct.pack("<H", 2)
           + cd_str("RESET") + bytes([21]) + cd_str("count again from start") + b"\1"
           + cd_type("CounterReset", 8, [("start", 8, 0, 1)])
           + cd_str("FREEZE") + bytes([22]) + cd_str("stop") + b"\0"
           + struct.pack("<H", 2)
           + cd_param("step", 1, 0, "1/s", 0.0, inf, "1", "growth per cycle")
           + cd_param("mode", 3, 3, "", -inf, inf, "up", "direction", ("up", "down")))
empty = (b"RKCD" + bytes([1, 0x40, 0, 0]) + cd_str("Gen") + cd_str("Generator") + cd_str("") + b"\0"
         + struct.pack("<HH", 0, 0))


def cd_pages(desc, size):
    out = b""
    for off in range(0, len(desc), size):
        body = struct.pack("<II", len(desc), off) + desc[off:off + size]
        out += struct.pack("<H", len(body)) + body
    return out


# With the optional value-names section (served to clients that ask): an enum field
# (state: IDLE, RUNNING, "2D") and an address field (owner).
named = (b"RKCD" + bytes([1, 0x91, 0, 0]) + cd_str("Counter") + cd_str("Counter") + cd_str("test: counts")
         + b"\1" + cd_type("CounterData", 32, [("count", 8, 0, 1), ("rate", 11, 8, 1), ("label", 3, 16, 8),
                                             ("state", 1, 24, 1), ("owner", 7, 28, 1)])
         + struct.pack("<HH", 0, 0)
         + struct.pack("<H", 2)
         + cd_str("state") + b"\0" + struct.pack("<H", 3) + struct.pack("<I", 0) + cd_str("IDLE")
         + struct.pack("<I", 1) + cd_str("RUNNING") + struct.pack("<I", 7) + cd_str("2D")
         + cd_str("owner") + b"\1" + struct.pack("<H", 0))
# With the optional field-units section after the value names (empty when the class
# names no values): u16 count, then {u16 field index, str unit} in field order.
units = (counter + struct.pack("<H", 0) + struct.pack("<H", 2) + struct.pack("<H", 0) + cd_str("1")
         + struct.pack("<H", 1) + cd_str("1/s"))
named_units = named + struct.pack("<H", 1) + struct.pack("<H", 1) + cd_str("1/s")
write("class_description", [b"\0" + counter, b"\0" + empty, b"\1" + cd_pages(counter, 8192),
                            b"\1" + cd_pages(empty, 8192), b"\1" + cd_pages(counter, 100),
                            b"\1" + struct.pack("<HII", 8, 4, 0), b"\0" + named,
                            b"\1" + cd_pages(named, 64), b"\0" + units, b"\0" + named_units,
                            b"\1" + cd_pages(named_units, 48), b"\x05" + cd_pages(units, 8192)])


# GET_LISTENERS' reply (wire::ListenersReply, 792 bytes), after one byte: bit 0 the
# body is in the host's (little-endian) byte order, bit 1 from the generator.
def listeners(e, data_task, period_ns, entries, total=None):
    n = len(entries)
    total = n if total is None else total
    pad = 32 - n
    body = struct.pack(e + "B3xIII", data_task, n, total, 0) + struct.pack(e + "q", period_ns)
    body += struct.pack(e + "32I", *([m for m, _, _, _ in entries] + [0] * pad))
    body += struct.pack(e + "32I", *([f for _, f, _, _ in entries] + [0] * pad))
    body += struct.pack(e + "32q", *([p for _, _, p, _ in entries] + [0] * pad))
    body += struct.pack(e + "32q", *([a for _, _, _, a in entries] + [0] * pad))
    return body


monitor_in = (0 << 24) | (0x41 << 16) | (0 << 8) | 3  # Monitor(0/0)#3
tool_data = (255 << 24) | (0x02 << 16) | (4 << 8) | 1  # Tool(255/4)#1
ms = 1000000
two = [(monitor_in, 1, 10 * ms, 2 * ms), (tool_data, 10, 100 * ms, 1500 * ms)]
many = [((255 << 24) | (0x02 << 16) | (i << 8) | 1, 1 + i, (1 + i) * 10 * ms, i * ms) for i in range(32)]
write("listeners", [b"\3" + listeners("<", 1, 10 * ms, []),
                    b"\3" + listeners("<", 1, 10 * ms, two[:1]),
                    b"\3" + listeners("<", 1, 10 * ms, two),
                    b"\2" + listeners(">", 1, 10 * ms, two),
                    b"\3" + listeners("<", 1, 10 * ms, many, 40),
                    b"\1" + listeners("<", 0, 0, []),
                    b"\3" + listeners("<", 2, 0, [(tool_data, 1, 0, 0)]),
                    b"\3" + listeners("<", 1, 10 * ms, two)[:700]])


# GET_TASKS' reply (wire::TasksReply version 1, 680 bytes; rack/core/wire_tasks.h),
# after one byte: bit 0 the body is in the host's (little-endian) byte order, bit 1
# from the generator, bit 2 the hosts were found by discovery (adopt_running).
def tasks(e, data_task, records, networks, online=2, version=1):
    # records: [(measured, policy, prio, last_cpu, conf_prio, conf_cpu, [4 affinity words],
    #            period, measured_period, sampled_ago)] for the command task, then the data task.
    recs = records + [(0, 0, 0, 0, 0, 0, [0, 0, 0, 0], 0, 0, 0)] * (2 - len(records))
    body = struct.pack(e + "BBBBI", version, data_task, len(records), len(networks), online)
    body += struct.pack(e + "2B2B4x", *[r[0] for r in recs], *[r[1] for r in recs])
    for k in (2, 3, 4, 5):
        body += struct.pack(e + "2i", *[r[k] for r in recs])
    body += struct.pack(e + "8Q", *(recs[0][6] + recs[1][6]))
    for k in (7, 8, 9):
        body += struct.pack(e + "2q", *[r[k] for r in recs])
    body += struct.pack(e + "4B4x", *([s for _, _, s in networks] + [0] * (4 - len(networks))))
    body += b"".join(n.encode().ljust(32, b"\0") for n, _, _ in networks).ljust(128, b"\0")
    body += b"".join(u.encode().ljust(96, b"\0") for _, u, _ in networks).ljust(384, b"\0")
    assert len(body) == 680, len(body)
    return body


cmd_run = (1, 1, 30, 1, 30, -1, [3, 0, 0, 0], 0, 0, 2 * ms)
gen_run = (1, 1, 40, 0, 40, 0, [1, 0, 0, 0], 10 * ms, 10 * ms + 20000, 2 * ms)
mon_run = (1, 1, 45, 0, 45, 0, [1, 0, 0, 0], 0, 100 * ms, 2 * ms)
fallback = (1, 0, 0, 1, 45, 0, [3, 0, 0, 0], 0, 0, 2 * ms)
unmeasured = (0, 0, 0, -1, 40, 0, [0, 0, 0, 0], 10 * ms, 0, 0)
robot = [("robot", "udpm://239.255.76.67:7667?ttl=0", 0)]
fleet = robot + [("fleet", "udpm://239.255.76.68:7700?ttl=1", 1)]
write("tasks", [b"\3" + tasks("<", 1, [cmd_run, gen_run], robot),
                b"\1" + tasks("<", 2, [cmd_run, mon_run], fleet),
                b"\7" + tasks("<", 1, [cmd_run, gen_run], robot),
                b"\5" + tasks("<", 2, [cmd_run, fallback], robot),
                b"\2" + tasks(">", 1, [cmd_run, gen_run], fleet),
                b"\7" + tasks("<", 1, [cmd_run, unmeasured], []),
                b"\5" + tasks("<", 0, [cmd_run], robot),
                b"\3" + tasks("<", 1, [cmd_run, gen_run], robot, version=2) + b"\0" * 16,
                b"\3" + tasks("<", 1, [cmd_run, gen_run], robot)[:600]])
