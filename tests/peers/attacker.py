#!/usr/bin/env python3
"""An attacker on the same machine as deckwatch's link, written with pymavlink: from a socket of
its own it sends, for `--duration-s`, the autopilot's attitude with a roll bias of `--bias-deg`
in every form a link must refuse, each at `--rate-hz`:

- unsigned, as the autopilot (system 1, component 1);
- signed with another key, as the autopilot;
- signed with the right key but from another system (a second vehicle sharing the key);
- the autopilot's own signed frames (`--replay FILE`, hex lines the autopilot captured), sent
  again later: a replay;
- MAVLink 1, a frame with its checksum broken, and bytes that are no frame;
- TIMESYNC answers and requests (to move deckwatch's clock, and to draw its replies here).

It listens on its socket the whole time: deckwatch must never send it anything. Prints a JSON
summary: what it sent by kind, and the datagrams it received.
"""

import os
os.environ.setdefault("MAVLINK20", "1")

import argparse
import json
import socket
import time

from pymavlink import mavutil
from pymavlink.dialects.v20 import common as mavlink2
from pymavlink.dialects.v10 import common as mavlink1

from autopilot import quaternion_ned


def packer(system, component, key=None, link_id=0):
    """A pymavlink encoder (no connection): `.pack(msg)` gives the frame's bytes."""
    mav = mavlink2.MAVLink(None, srcSystem=system, srcComponent=component)
    if key is not None:
        mav.signing.secret_key = key
        mav.signing.sign_outgoing = True
        mav.signing.link_id = link_id
        mav.signing.timestamp = int((time.time() - 1420070400) * 1e5)
    return mav


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--port", type=int, required=True, help="deckwatch's udpin port on 127.0.0.1")
    ap.add_argument("--key-hex", required=True, help="the link's key (for the second vehicle)")
    ap.add_argument("--tilt-deg", type=float, nargs=3, default=[0.0, 0.0, 0.0])
    ap.add_argument("--bias-deg", type=float, default=5.0)
    ap.add_argument("--clock-offset-s", type=float, default=0.0)
    ap.add_argument("--replay", required=True, help="the autopilot's captured frames, hex per line")
    ap.add_argument("--start-after-s", type=float, default=3.0)
    ap.add_argument("--duration-s", type=float, default=6.0)
    ap.add_argument("--rate-hz", type=float, default=50.0)
    ap.add_argument("--kinds", default="all",
                    help="comma-separated kinds to send (unsigned, other-key, other-system, replay, mavlink1, bad-crc, junk, timesync), or all")
    a = ap.parse_args()
    # The autopilot writes its captured frames in its first second.
    capture_deadline = time.monotonic() + a.start_after_s + 10.0

    key = bytes.fromhex(a.key_hex)
    sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    sock.bind(("127.0.0.1", 0))
    sock.settimeout(0.002)
    to = ("127.0.0.1", a.port)
    roll, pitch, yaw = a.tilt_deg
    q = quaternion_ned(roll + a.bias_deg, pitch, yaw)
    # The autopilot's clock (as if the attacker knew it): only the bias gives it away.
    offset_ns = int(a.clock_offset_s * 1e9)

    def boot_ms():
        return int((time.monotonic_ns() + offset_ns) / 1e6) & 0xFFFFFFFF

    unsigned = packer(1, 1)
    other_key = packer(1, 1, key=bytes(range(32)), link_id=7)
    other_system = packer(2, 1, key=key, link_id=9)
    v1 = mavlink1.MAVLink(None, srcSystem=1, srcComponent=1)

    sent = {}
    received = 0

    kinds = None if a.kinds == "all" else set(a.kinds.split(","))

    def send(kind, data):
        if kinds is not None and kind not in kinds:
            return
        sock.sendto(data, to)
        sent[kind] = sent.get(kind, 0) + 1

    def attitude(mav):
        return mav.attitude_quaternion_encode(boot_ms(), q[0], q[1], q[2], q[3], 0, 0, 0).pack(mav)

    def listen_until(deadline):
        nonlocal received
        while time.monotonic() < deadline:
            try:
                sock.recvfrom(4096)
                received += 1
            except socket.timeout:
                pass

    listen_until(time.monotonic() + a.start_after_s)
    while not os.path.exists(a.replay) and time.monotonic() < capture_deadline:
        listen_until(time.monotonic() + 0.1)
    with open(a.replay) as f:
        replay = [bytes.fromhex(line.strip()) for line in f if line.strip()]
    period = 1.0 / a.rate_hz
    end = time.monotonic() + a.duration_s
    k = 0
    while time.monotonic() < end:
        send("unsigned", attitude(unsigned))
        send("other-key", attitude(other_key))
        send("other-system", attitude(other_system))
        if replay:
            send("replay", replay[k % len(replay)])
        send("mavlink1", v1.attitude_encode(boot_ms(), 0.1, 0.0, 0.0, 0, 0, 0).pack(v1))
        broken = bytearray(attitude(unsigned))
        broken[-3] ^= 0x5A
        send("bad-crc", bytes(broken))
        send("junk", os.urandom(40).replace(b"\xfd", b"\x00").replace(b"\xfe", b"\x00"))
        # A TIMESYNC answer that would move the clock by an hour, and a request to draw a reply.
        send("timesync", unsigned.timesync_encode(3_600_000_000_000, 1).pack(unsigned))
        send("timesync", other_key.timesync_encode(0, 42).pack(other_key))
        k += 1
        listen_until(time.monotonic() + period)
    listen_until(time.monotonic() + 1.0)
    print(json.dumps({"sent": sent, "received": received}))


if __name__ == "__main__":
    main()
