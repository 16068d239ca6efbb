"""The link under a flood (issue 34): the whole pipeline on the simulator (`deckwatch run`, the
link requiring MAVLink 2 signing), pymavlink as the autopilot (tests/peers/autopilot.py: a 100 Hz
signed attitude stream, LOCAL_POSITION_NED, TIMESYNC), and a flooder on another loopback socket
sending `--flood-hz` junk and spoofed frames a second for `--flood-s` seconds (unsigned copies of
the autopilot's attitude with a 5 deg bias, the same signed with another key, frames with a
broken checksum, MAVLink 1 frames and bytes that are no frame, in turn). Run twice, quiet and
flooded, and compared:

- decisions: decide's (the `--decisions` CSV rows) against those the link forwarded;
- vehicle samples: the link's attitudes in, and the autopilot's frames lost on the way (the gaps
  in its MAVLink sequence numbers: a flood that filled the socket would push them out);
- latency: each LANDING_TARGET's age when the autopilot received it (capture to the autopilot, on
  the autopilot's clock: the whole pipeline and the link's send), p50 / p99 / max;
- what the link refused, by cause, and the flooder's achieved rate.

Usage: python3 bench/link_flood.py DECKWATCH_BINARY [--flood-hz 20000] [--flood-s 30]
(the stage binaries beside DECKWATCH_BINARY; a release build). Needs pymavlink (ci/peers.sh).
Prints a markdown table.
"""
import argparse
import json
import os
import socket
import statistics
import subprocess
import sys
import tempfile
import threading
import time

HERE = os.path.dirname(os.path.abspath(__file__))
PEERS = os.path.join(HERE, "..", "tests", "peers")
sys.path.insert(0, PEERS)
os.environ.setdefault("MAVLINK20", "1")
from pymavlink.dialects.v20 import common as mavlink2  # noqa: E402
from pymavlink.dialects.v10 import common as mavlink1  # noqa: E402

from autopilot import quaternion_ned  # noqa: E402

TILT_DEG = [4.0, -3.0, 0.0]
RATE_HZ = 30


def flood_frames(n=1000):
    """`n` frames to cycle through: spoofed attitudes (unsigned, another key), broken, MAVLink 1,
    junk."""
    q = quaternion_ned(TILT_DEG[0] + 5.0, TILT_DEG[1], TILT_DEG[2])
    unsigned = mavlink2.MAVLink(None, srcSystem=1, srcComponent=1)
    other = mavlink2.MAVLink(None, srcSystem=1, srcComponent=1)
    other.signing.secret_key = bytes(range(32))
    other.signing.sign_outgoing = True
    other.signing.link_id = 3
    other.signing.timestamp = int((time.time() - 1420070400) * 1e5)
    v1 = mavlink1.MAVLink(None, srcSystem=1, srcComponent=1)
    frames = []
    for k in range(n):
        kind = k % 5
        if kind == 0:
            frames.append(unsigned.attitude_quaternion_encode(k, *q, 0, 0, 0).pack(unsigned))
        elif kind == 1:
            frames.append(other.attitude_quaternion_encode(k, *q, 0, 0, 0).pack(other))
        elif kind == 2:
            b = bytearray(unsigned.attitude_quaternion_encode(k, *q, 0, 0, 0).pack(unsigned))
            b[-1] ^= 0xA5
            frames.append(bytes(b))
        elif kind == 3:
            frames.append(v1.attitude_encode(k, 0.1, 0.0, 0.0, 0, 0, 0).pack(v1))
        else:
            frames.append(os.urandom(48).replace(b"\xfd", b"\x01").replace(b"\xfe", b"\x01"))
    return frames


def flood(port, hz, seconds, start_after_s, out):
    """Sends `hz` frames a second from its own socket, paced per millisecond."""
    frames = flood_frames()
    sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    sock.bind(("127.0.0.1", 0))
    time.sleep(start_after_s)
    start = time.monotonic()
    sent = 0
    k = 0
    while True:
        elapsed = time.monotonic() - start
        if elapsed >= seconds:
            break
        due = int(elapsed * hz)
        while sent < due:
            try:
                sock.sendto(frames[k], ("127.0.0.1", port))
            except OSError:
                pass  # a full socket buffer: the frame is lost, as on a network
            k = (k + 1) % len(frames)
            sent += 1
        time.sleep(0.0005)
    out["sent"] = sent
    out["seconds"] = time.monotonic() - start


def free_port():
    s = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    s.bind(("127.0.0.1", 0))
    p = s.getsockname()[1]
    s.close()
    return p


def run(deckwatch, flood_hz, flood_s, python):
    d = tempfile.mkdtemp(prefix="dwflood")
    key = os.urandom(32)
    key_file = os.path.join(d, "mavlink.key")
    fd = os.open(key_file, os.O_WRONLY | os.O_CREAT | os.O_EXCL, 0o600)
    os.write(fd, key)
    os.close(fd)
    port = free_port()
    domain = f"flood{os.getpid()}x{flood_hz}"
    # The stream before and after the flood: 4 s + the flood + 4 s of frames.
    frames = int((flood_s + 8) * RATE_HZ)
    config = os.path.join(d, "p.toml")
    r, p, y = TILT_DEG
    state_file = os.path.join(d, "signing.state")
    with open(config, "w") as f:
        f.write(
            f'[bus]\ndomain = "{domain}"\n'
            f'[sim]\nvehicle = "tilted"\nvehicle_tilt_deg = [{r}, {p}, {y}]\nframes = {frames}\nrate = {RATE_HZ}\n'
            f'[vehicle]\nattitude = "autopilot"\n'
            f'[link]\nenabled = true\naddress = "udpin:127.0.0.1:{port}"\nsigning = "required"\n'
            f'signing_key_file = "{key_file}"\nsigning_state_file = "{state_file}"\n'
            f'[rerun]\nsink = "off"\n'
        )
    decisions = os.path.join(d, "decisions.csv")
    stream_s = frames / RATE_HZ + 6
    autopilot = subprocess.Popen(
        [python, os.path.join(PEERS, "autopilot.py"), "--port", str(port),
         "--tilt-deg", *map(str, TILT_DEG), "--stop-after-s", str(stream_s), "--linger-s", "2",
         "--tlog", os.path.join(d, "s.tlog"), "--key-hex", key.hex()],
        stdout=subprocess.PIPE,
    )
    flooded = {}
    flooder = threading.Thread(target=flood, args=(port, flood_hz, flood_s, 6.0, flooded))
    if flood_hz > 0:
        flooder.start()
    pipeline = subprocess.run(
        [deckwatch, "run", "--quiet", "--config", config, "--decisions", decisions],
        stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
    )
    if flood_hz > 0:
        flooder.join()
    seen = json.loads(autopilot.communicate()[0])
    if pipeline.returncode != 0:
        raise SystemExit(f"deckwatch run failed:\n{pipeline.stderr}")
    summary = next(
        (line for line in pipeline.stderr.splitlines() if "deckwatch-link:" in line and "frames admitted" in line),
        None,
    )
    if summary is None:
        raise SystemExit(f"no link summary:\n{pipeline.stderr}")
    with open(decisions) as f:
        decided = sum(1 for _ in f) - 1
    forwarded = int(summary.split(" decisions (")[0].rsplit(" ", 1)[1])
    attitudes_in = int(summary.split(" attitudes (")[0].rsplit(" ", 1)[1])
    lost = int(summary.split(" of the autopilot's lost")[0].rsplit(" ", 1)[1])
    refused = summary.split(" refused (")[1].split(")")[0]
    ages_ms = sorted((t["recv_autopilot_us"] - t["time_usec"]) / 1e3 for t in seen["landing_targets"])

    def pct(q):
        return ages_ms[min(len(ages_ms) - 1, int(q * len(ages_ms)))] if ages_ms else float("nan")

    return {
        "flood_hz": flood_hz,
        "flood_rate": flooded.get("sent", 0) / flooded["seconds"] if flooded else 0.0,
        "decided": decided,
        "forwarded": forwarded,
        "attitudes_in": attitudes_in,
        "lost": lost,
        "targets": len(ages_ms),
        "p50": statistics.median(ages_ms) if ages_ms else float("nan"),
        "p99": pct(0.99),
        "max": ages_ms[-1] if ages_ms else float("nan"),
        "refused": refused,
    }


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("deckwatch")
    ap.add_argument("--flood-hz", type=int, default=20000)
    ap.add_argument("--flood-s", type=float, default=30.0)
    a = ap.parse_args()
    python = sys.executable
    rows = [run(a.deckwatch, hz, a.flood_s, python) for hz in (0, a.flood_hz)]
    print("| run | flood frames/s (achieved) | decisions made / forwarded | autopilot attitudes in / its frames lost | LANDING_TARGET age at the autopilot p50 / p99 / max (ms) | refused by the link |")
    print("| --- | --- | --- | --- | --- | --- |")
    for r in rows:
        name = "quiet" if r["flood_hz"] == 0 else "flooded"
        print(
            f"| {name} | {r['flood_hz']} ({r['flood_rate']:.0f}) | {r['decided']} / {r['forwarded']} | "
            f"{r['attitudes_in']} / {r['lost']} | {r['p50']:.1f} / {r['p99']:.1f} / {r['max']:.1f} "
            f"({r['targets']}) | {r['refused']} |"
        )
    print(json.dumps(rows))


if __name__ == "__main__":
    main()
