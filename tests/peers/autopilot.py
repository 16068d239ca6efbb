#!/usr/bin/env python3
"""A stand-in autopilot and ground station for deckwatch's link, written with pymavlink (an
implementation nobody in deckwatch wrote).

It streams HEARTBEAT and ATTITUDE_QUATERNION (a constant tilt, on its own clock that is
`--clock-offset-s` ahead of CLOCK_MONOTONIC), answers TIMESYNC requests, and records what
deckwatch sends: every message into a telemetry log (`--tlog`, read back by mavlogdump.py), and a
JSON summary on stdout. After `--stop-after-s` it stops its attitude stream (a link loss) and
keeps listening for `--linger-s`. With `--key-hex` it signs what it sends and accepts only frames
signed with that key (pymavlink's MAVLink 2 signing); `--capture FILE` keeps its first signed
attitude frames there (hex, one a line) for an attacker to replay.
"""

import os
os.environ.setdefault("MAVLINK20", "1")  # deckwatch speaks MAVLink 2 only

import argparse
import json
import math
import struct
import time

from pymavlink import mavutil


def quaternion_ned(roll_deg, pitch_deg, yaw_deg):
    """MAVLink's FRD->NED quaternion of a vehicle tilted by deckwatch's FLU angles
    (R_V = Rx(roll) Ry(pitch) Rz(yaw), body FLU to north-west-up): MAVLink's own Euler order is
    Z-Y-X, so go through the matrix."""
    r, p, y = (math.radians(a) for a in (roll_deg, pitch_deg, yaw_deg))
    cr, sr, cp, sp, cy, sy = math.cos(r), math.sin(r), math.cos(p), math.sin(p), math.cos(y), math.sin(y)
    rx = [[1, 0, 0], [0, cr, -sr], [0, sr, cr]]
    ry = [[cp, 0, sp], [0, 1, 0], [-sp, 0, cp]]
    rz = [[cy, -sy, 0], [sy, cy, 0], [0, 0, 1]]

    def mul(a, b):
        return [[sum(a[i][k] * b[k][j] for k in range(3)) for j in range(3)] for i in range(3)]

    flu = mul(mul(rx, ry), rz)
    f = [1, -1, -1]  # FLU<->FRD and NWU<->NED: diag(1, -1, -1) on both sides
    m = [[f[i] * flu[i][j] * f[j] for j in range(3)] for i in range(3)]
    w = math.sqrt(max(0.0, 1 + m[0][0] + m[1][1] + m[2][2])) / 2
    return [w, (m[2][1] - m[1][2]) / (4 * w), (m[0][2] - m[2][0]) / (4 * w), (m[1][0] - m[0][1]) / (4 * w)]


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--port", type=int, required=True, help="deckwatch's udpin port on 127.0.0.1")
    ap.add_argument("--tilt-deg", type=float, nargs=3, default=[0.0, 0.0, 0.0])
    ap.add_argument("--rate-hz", type=float, default=100.0)
    ap.add_argument("--height-m", type=float, default=5.0,
                    help="the vehicle's height in the local frame (LOCAL_POSITION_NED at 30 Hz)")
    ap.add_argument("--clock-offset-s", type=float, default=0.0)
    ap.add_argument("--stop-after-s", type=float, required=True)
    ap.add_argument("--linger-s", type=float, default=3.0)
    ap.add_argument("--tlog", required=True)
    ap.add_argument("--key-hex", help="sign with this 32-byte key; refuse frames not signed with it")
    ap.add_argument("--capture", help="write the first signed attitude frames here (hex lines)")
    a = ap.parse_args()

    conn = mavutil.mavlink_connection(
        f"udpout:127.0.0.1:{a.port}", source_system=1, source_component=1, dialect="common"
    )
    # A telemetry log (.tlog: each message with a big-endian microsecond timestamp), written here
    # because pymavlink's UDP connection does not log what it receives.
    tlog = open(a.tlog, "wb")
    mav = conn.mav
    if a.key_hex:
        conn.setup_signing(bytes.fromhex(a.key_hex), sign_outgoing=True, link_id=1)
    captured = []
    q = quaternion_ned(*a.tilt_deg)
    offset_ns = int(a.clock_offset_s * 1e9)

    def boot_ns():
        return time.monotonic_ns() + offset_ns

    start = time.monotonic_ns()
    stop_ns = start + int(a.stop_after_s * 1e9)
    end_ns = stop_ns + int(a.linger_s * 1e9)
    period_ns = int(1e9 / a.rate_hz)
    next_attitude = start
    next_heartbeat = start
    next_position = start
    out = {
        "stop_monotonic_ns": stop_ns,
        "attitudes_sent": 0,
        "timesync_answered": 0,
        "counts": {},
        "landing_targets": [],
        "states": [],
        "floats": {},
        "texts": [],
        "heartbeats_from": [],
    }
    while True:
        now = time.monotonic_ns()
        if now >= end_ns:
            break
        streaming = now < stop_ns
        if streaming and now >= next_heartbeat:
            mav.heartbeat_send(
                mavutil.mavlink.MAV_TYPE_QUADROTOR, mavutil.mavlink.MAV_AUTOPILOT_PX4, 0, 0,
                mavutil.mavlink.MAV_STATE_ACTIVE,
            )
            next_heartbeat += 1_000_000_000
        if streaming and now >= next_attitude:
            m = mav.attitude_quaternion_encode(int(boot_ns() / 1e6) & 0xFFFFFFFF, q[0], q[1], q[2], q[3], 0, 0, 0)
            mav.send(m)
            out["attitudes_sent"] += 1
            if a.capture and len(captured) < 50:
                captured.append(m.get_msgbuf().hex())
                if len(captured) == 50:
                    with open(a.capture + ".part", "w") as f:
                        f.write("\n".join(captured) + "\n")
                    os.rename(a.capture + ".part", a.capture)
            next_attitude += period_ns
        if streaming and now >= next_position:
            # NED: z is down; holding its height, the vehicle does not move.
            mav.local_position_ned_send(int(boot_ns() / 1e6) & 0xFFFFFFFF, 0, 0, -a.height_m, 0, 0, 0)
            next_position += 33_333_333
        # Receive until the next thing to send is due.
        m = conn.recv_match(blocking=True, timeout=0.002)
        if m is None:
            continue
        t = m.get_type()
        if t == "BAD_DATA":
            out["counts"]["BAD_DATA"] = out["counts"].get("BAD_DATA", 0) + 1
            continue
        tlog.write(struct.pack(">Q", int(time.time() * 1e6)) + m.get_msgbuf())
        out["counts"][t] = out["counts"].get(t, 0) + 1
        recv = time.monotonic_ns()
        if t == "TIMESYNC" and m.tc1 == 0:
            mav.timesync_send(boot_ns(), m.ts1)
            out["timesync_answered"] += 1
        elif t == "LANDING_TARGET":
            out["landing_targets"].append({
                "recv_ns": recv,
                "recv_autopilot_us": boot_ns() // 1000,
                "time_usec": m.time_usec,
                "frame": m.frame,
                "position_valid": m.position_valid,
                "xyz": [m.x, m.y, m.z],
                "q": list(m.q),
                "angle": [m.angle_x, m.angle_y],
                "distance": m.distance,
            })
        elif t == "NAMED_VALUE_INT" and m.name == "dw_state":
            out["states"].append([recv, m.value])
        elif t == "NAMED_VALUE_FLOAT":
            # NaN (not measured) has no JSON form: null.
            out["floats"].setdefault(m.name, []).append(m.value if math.isfinite(m.value) else None)
        elif t == "STATUSTEXT":
            out["texts"].append([recv, m.severity, m.text])
        elif t == "HEARTBEAT":
            out["heartbeats_from"].append([m.get_srcSystem(), m.get_srcComponent(), m.type])
    tlog.close()
    print(json.dumps(out))


if __name__ == "__main__":
    main()
