#!/usr/bin/env python3
"""Another local user against deckwatch's shared memory (run as that user; standard library only).

--squat PATH...: makes each folder first, open to everyone (mode 0777), as a user who knows the
  names the pipeline will use would: iceoryx2's default root /tmp/iceoryx2, or deckwatch's own.
--attack-root DIR --shm-prefix P: tries to write into a running pipeline: a file in its iceoryx2
  root and in the root's services folder, every shared-memory segment /dev/shm/P* opened for
  writing, and a datagram to every event socket in the root.

Prints a JSON summary: what it squatted, and for each attempt whether it was denied.
"""

import argparse
import glob
import json
import os
import socket


def attempt(out, what, action):
    try:
        action()
        out["written"].append(what)
    except OSError as e:
        out["denied"].append(f"{what}: {e.strerror}")


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--squat", nargs="*", default=[])
    ap.add_argument("--attack-root")
    ap.add_argument("--shm-prefix")
    a = ap.parse_args()
    out = {"uid": os.getuid(), "squatted": [], "written": [], "denied": []}
    for path in a.squat:
        try:
            os.mkdir(path, 0o777)
            os.chmod(path, 0o777)
            out["squatted"].append(path)
        except FileExistsError:
            pass
    if a.attack_root:
        root = a.attack_root

        def plant(folder):
            with open(os.path.join(folder, "iox2_planted.service"), "wb") as f:
                f.write(b"planted by another user")

        attempt(out, f"a file in {root}", lambda: plant(root))
        attempt(out, f"a service file in {root}/services", lambda: plant(os.path.join(root, "services")))
        attempt(out, f"listing {root}", lambda: os.listdir(root))
        try:
            sockets = [os.path.join(root, n) for n in os.listdir(root) if n.endswith(".event")]
        except OSError:
            sockets = []
        for path in sockets:
            def send(path=path):
                s = socket.socket(socket.AF_UNIX, socket.SOCK_DGRAM)
                try:
                    s.sendto(b"\x01" * 8, path)
                finally:
                    s.close()
            attempt(out, f"a datagram to {path}", send)
    if a.shm_prefix:
        for path in sorted(glob.glob(f"/dev/shm/{a.shm_prefix}*")):
            def scribble(path=path):
                with open(path, "r+b") as f:
                    f.write(b"\xff" * 64)
            attempt(out, f"writing {path}", scribble)
    print(json.dumps(out))


if __name__ == "__main__":
    main()
