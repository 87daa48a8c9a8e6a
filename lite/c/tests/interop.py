"""Interoperability check between AylluLite C and AylluLite Python over real UDP on 127.0.0.1.

What it is for: the golden vectors prove each implementation against the spec's bytes; this
proves the two *nodes* talk to each other -- the C example client writes a port exposed by a
Python LiteNode (open and keyed teams, a special connection kind; a keyed team given by flags
and, once, only by the AYLLU_URL every Ayllu program reads) and reads it back with a READ
request the Python node answers. Usage: python3 interop.py PATH/TO/udp_client.
Exits non-zero on any mismatch.
"""

import os
import subprocess
import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[2] / "python"))
import ayllu_lite as al

CLIENT = sys.argv[1]
KEY_HEX = "00112233445566778899aabbccddeeff00112233445566778899aabbccddeeff"


def run(*args: str, url: str | None = None) -> str:
    # The caller's own AYLLU_URL must not leak into the check.
    env = {k: v for k, v in os.environ.items() if k != "AYLLU_URL"}
    if url is not None:
        env["AYLLU_URL"] = url
    out = subprocess.run([CLIENT, *args], check=False, capture_output=True, text=True, timeout=15, env=env)
    if out.returncode != 0:
        raise SystemExit(f"udp_client {' '.join(args)} failed: {out.stderr.strip()}")
    return out.stdout.strip()


def check(key: bytes | None, by_url: bool = False) -> None:
    # By flags (--team 7, --key) or by the URL alone (team=7&key=...).
    url = f"udp://0.0.0.0:0?team=7&key={KEY_HEX}" if by_url else None
    team = [] if by_url else ["--team", "7"]
    extra = team + (["--key", KEY_HEX] if key and not by_url else [])
    seen: list[tuple[object, ...]] = []
    with al.LiteNode(1, 7, key=key, bind=("127.0.0.1", 0)) as node:
        node.expose("Drive", "Speed", 0.0, on_write=lambda *a: seen.append(a))
        node.expose("Drive", "Mode", "")
        node.start()
        host, port = node.address
        run("--node", "900", *extra, host, str(port), "Drive", "Speed", "2.5", url=url)
        special = ["--kind", "override-in", "--period-ms", "300"]
        run(*extra, *special, host, str(port), "Drive", "Mode", "auto", url=url)
        deadline = time.monotonic() + 5
        while (node.get("Drive", "Speed"), node.get("Drive", "Mode")) != (2.5, "auto"):
            if time.monotonic() > deadline:
                raise SystemExit(f"values never arrived: {node.ports()} counters {node.counters}")
            time.sleep(0.01)
        assert seen[0][2:4] == (2.5, 900), seen
        got = run(*extra, "--read", host, str(port), "Drive", "Speed", url=url)
        if got != "2.5":
            raise SystemExit(f"READ gave {got!r}")
        drops = {k: v for k, v in node.counters.items() if k not in ("received", "sent")}
        if drops:
            raise SystemExit(f"unexpected drops: {drops}")
    how = " from AYLLU_URL" if by_url else ""
    print(f"interop: C client -> Python node ok ({'keyed' if key else 'open'} team{how})")


check(None)
check(bytes.fromhex(KEY_HEX))
check(bytes.fromhex(KEY_HEX), by_url=True)
