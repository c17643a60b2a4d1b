#!/usr/bin/env python3
"""Helpers of deploy/faults.sh: hostile clients (garbage frames, a connection flood), the
comparison of a fault run's trajectories with the fault-free run's, and the campaign's table.

  faults_tools.py garbage SECONDS HOST:PORT...        random bytes, bad greetings, 2^62-byte frames
  faults_tools.py flood SECONDS PER_PORT HOST:PORT... idle connections held open (reopened if shut)
  faults_tools.py row NAME N DIR REF WALL_S CODES [NOTE]  one table row (JSON) on stdout
  faults_tools.py table ROWS_JSONL                     the table; exit 1 if a fault did not heal
"""
import json
import math
import os
import random
import resource
import errno
import selectors
import signal
import socket
import struct
import sys
import time

TOLERANCE_M = 1e-6  # issue 19: healed means the same certified result within 1e-6 m


def endpoints(args):
    out = []
    for a in args:
        host, port = a.rsplit(":", 1)
        out.append((host, int(port)))
    return out


def greeting(mechanism):
    """A ZMTP 3.0 greeting (signature, version, mechanism, as-server, filler)."""
    return (b"\xff" + b"\x00" * 8 + b"\x7f" + b"\x03\x00" + mechanism.ljust(20, b"\x00") +
            b"\x00" + b"\x00" * 31)


def garbage_payloads(rng):
    oversized = b"\x02" + struct.pack(">Q", 1 << 62) + rng.randbytes(64)  # long frame, 2^62 B
    return [
        rng.randbytes(4096),
        greeting(b"NULL") + oversized,
        greeting(b"CURVE") + b"\x04" + bytes([200]) + b"\x05HELLO" + rng.randbytes(199),
        greeting(b"CURVE") + oversized,
        greeting(b"PLAIN") + b"\x06" + struct.pack(">Q", 1 << 40) + b"\x05HELLO",
        b"\xff" + b"\x00" * 8 + b"\x7f" + rng.randbytes(54),
    ]


def garbage(seconds, targets):
    """Sends each kind of malformed input to every port, over and over, for SECONDS."""
    rng = random.Random(19)
    sent = 0
    end = time.monotonic() + seconds
    while time.monotonic() < end:
        for host, port in targets:
            for payload in garbage_payloads(rng):
                try:
                    with socket.create_connection((host, port), timeout=0.5) as s:
                        s.sendall(payload)
                        sent += 1
                except OSError:
                    pass
        time.sleep(0.05)
    print(json.dumps({"garbage_connections": sent}))


def flood(seconds, per_port, targets):
    """Holds PER_PORT idle connections open on each port, reopening those the server closes,
    until SECONDS pass or SIGINT/SIGTERM; prints what it opened and what the server closed."""
    soft, hard = resource.getrlimit(resource.RLIMIT_NOFILE)
    want = min(hard, per_port * len(targets) + 256)
    if soft < want:
        resource.setrlimit(resource.RLIMIT_NOFILE, (want, hard))
    stop = []
    for sig in (signal.SIGINT, signal.SIGTERM):
        signal.signal(sig, lambda *_: stop.append(1))
    sel = selectors.DefaultSelector()  # epoll: descriptors beyond select()'s 1024
    count = {t: 0 for t in targets}
    opened = closed = failed = 0
    end = time.monotonic() + seconds
    while time.monotonic() < end and not stop:
        for target in targets:
            while count[target] < per_port:
                s = socket.socket(socket.AF_INET, socket.SOCK_STREAM)
                s.setblocking(False)
                if s.connect_ex(target) not in (0, errno.EINPROGRESS):
                    s.close()
                    failed += 1
                    break
                sel.register(s, selectors.EVENT_READ, target)
                count[target] += 1
                opened += 1
        for key, _ in sel.select(0.2):  # end of stream or reset: the server dropped it
            try:
                if key.fileobj.recv(4096):
                    continue
            except BlockingIOError:
                continue
            except OSError:
                pass
            sel.unregister(key.fileobj)
            key.fileobj.close()
            count[key.data] -= 1
            closed += 1
        if failed:
            time.sleep(0.1)
    print(json.dumps({"flood_opened": opened, "flood_closed_by_server": closed,
                      "flood_connect_errors": failed, "flood_held_at_end": sum(count.values())}))


def read_tum(path):
    poses = {}
    with open(path) as f:
        for line in f:
            parts = line.split()
            if len(parts) >= 4 and not parts[0].startswith("#"):
                poses[parts[0]] = tuple(float(v) for v in parts[1:4])
    return poses


def max_difference(run_dir, ref_dir, n):
    """Largest position difference (m) between the two runs' trajectories, inf when they differ
    in keyframes or a trajectory is missing."""
    worst = 0.0
    for k in range(n):
        try:
            run = read_tum(os.path.join(run_dir, f"robot{k}.tum"))
            ref = read_tum(os.path.join(ref_dir, f"robot{k}.tum"))
        except OSError:
            return math.inf
        if not ref or run.keys() != ref.keys():
            return math.inf
        for stamp, p in ref.items():
            worst = max(worst, math.dist(p, run[stamp]))
    return worst


def certified(run_dir, n):
    for k in range(n):
        try:
            with open(os.path.join(run_dir, f"robot{k}.report.json")) as f:
                if not json.load(f).get("certified"):
                    return False
        except (OSError, ValueError):
            return False
    return True


def row(name, n, run_dir, ref_dir, wall_s, codes, note=""):
    n = int(n)
    exit_codes = [int(c) for c in codes.split(",")] if codes else []
    diff = max_difference(run_dir, ref_dir, n)
    is_certified = bool(exit_codes) and certified(run_dir, n) and all(c == 0 for c in exit_codes)
    r = {
        "fault": name,
        "robots": n,
        "healed": is_certified and diff <= TOLERANCE_M,
        "certified": is_certified,
        "max_difference_m": diff if math.isfinite(diff) else None,
        "wall_s": round(float(wall_s), 1),
        "exit_codes": exit_codes,
    }
    if note.startswith("skipped:"):
        r.update(healed=None, certified=None, exit_codes=None,
                 skipped=note[len("skipped:"):].strip())
    elif note.startswith("failed:"):
        r.update(healed=False, note=note[len("failed:"):].strip())
    elif note:
        r["note"] = note
    print(json.dumps(r))


def table(path):
    with open(path) as f:
        rows = [json.loads(line) for line in f if line.strip()]
    print(json.dumps(rows, indent=1))
    failed = [r["fault"] + f" ({r['robots']} robots)" for r in rows if r["healed"] is False]
    skipped = [r["fault"] + f" ({r['robots']} robots)" for r in rows if r["healed"] is None]
    if skipped:
        print("faults: skipped: " + ", ".join(skipped), file=sys.stderr)
    if failed:
        print("faults: NOT healed: " + ", ".join(failed), file=sys.stderr)
        return 1
    faults = sum(r["fault"] != "reference" for r in rows)
    print(f"faults: {faults - len(skipped)} faults healed to the fault-free certified result "
          f"within {TOLERANCE_M} m", file=sys.stderr)
    return 0


def main(argv):
    cmd = argv[1] if len(argv) > 1 else ""
    if cmd == "garbage":
        garbage(float(argv[2]), endpoints(argv[3:]))
    elif cmd == "flood":
        flood(float(argv[2]), int(argv[3]), endpoints(argv[4:]))
    elif cmd == "row":
        row(*argv[2:])
    elif cmd == "table":
        return table(argv[2])
    else:
        print(__doc__, file=sys.stderr)
        return 2
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv))
