#!/usr/bin/python3
"""The dashboard's front door under a connection-filling attack, against a real vsurg-server.

Starts vsurg-server (all-in-one, a temporary SQLite file, --http on loopback, its default limits:
512 connections, 64 per address), then:
  1. ATTACKERS addresses (127.0.0.2…) each open PER_ADDRESS connections and send half a request
     (a header that never ends: the connections stay open until the request deadline);
  2. a legitimate user signs in from an address of their own, SIGNINS times, and we time each;
  3. MANY addresses each open 4 more half-requests (every connection taken), and the user signs
     in again (an idle connection of the heaviest address is closed to admit them).
Prints what the server holds and each sign-in's status and time, as JSON on the last line.

usage: bench/front_door.py BIN_DIR [ATTACKERS=8] [PER_ADDRESS=64] [MANY=120] [SIGNINS=5]
"""
import json
import os
import socket
import subprocess
import sys
import tempfile
import time
import urllib.request


def main():
    bin_dir = sys.argv[1]
    attackers = int(sys.argv[2]) if len(sys.argv) > 2 else 8
    per_address = int(sys.argv[3]) if len(sys.argv) > 3 else 64
    many = int(sys.argv[4]) if len(sys.argv) > 4 else 120
    signins = int(sys.argv[5]) if len(sys.argv) > 5 else 5
    root = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
    tmp = tempfile.mkdtemp(prefix="vsurg-front-door-")
    db = os.path.join(tmp, "vsurg.db")
    token = subprocess.run([f"{bin_dir}/vsurg-server", "init", "--db", db], check=True,
                           capture_output=True, text=True).stdout.strip().splitlines()[-1]
    ready = os.path.join(tmp, "ready.json")
    env = dict(os.environ, VSURG_SCENES=os.path.join(root, "scenes"))
    server = subprocess.Popen(
        [f"{bin_dir}/vsurg-server", "--db", db, "--listen", "127.0.0.1:0", "--udp-port", "0",
         "--http", "127.0.0.1:0", "--ready-file", ready], env=env,
        stderr=open(os.path.join(tmp, "server.log"), "w"))
    try:
        for _ in range(200):
            if os.path.exists(ready) and os.path.getsize(ready) > 0:
                break
            time.sleep(0.05)
        port = json.load(open(ready))["http_port"]

        def hold(address, count):
            opened, refused = [], 0
            for _ in range(count):
                s = socket.socket()
                s.bind((address, 0))
                s.settimeout(2)
                try:
                    s.connect(("127.0.0.1", port))
                    s.sendall(b"GET /signin HTTP/1.1\r\nHost: 127.0.0.1\r\n")
                    opened.append(s)
                except OSError:
                    refused += 1
                    s.close()
            return opened

        def alive(sockets):
            # Open as the client sees it; one the server refused (503), closed or reset is not.
            n, seen = 0, {"open": 0, "503": 0, "closed": 0, "reset": 0, "other": 0}
            for s in sockets:
                s.setblocking(False)
                try:
                    data = s.recv(64)
                    key = ("closed" if data == b"" else
                           "503" if data.startswith(b"HTTP/1.1 503") else "other")
                except BlockingIOError:
                    key = "open"
                except OSError:
                    key = "reset"
                seen[key] += 1
                s.setblocking(True)
            print(seen, file=sys.stderr)
            return seen["open"]

        def sign_in(address):
            body = json.dumps({"token": token}).encode()
            s = socket.create_connection(("127.0.0.1", port), timeout=10,
                                         source_address=(address, 0))
            t0 = time.monotonic()
            s.sendall(b"POST /api/v1/signin HTTP/1.1\r\nHost: 127.0.0.1\r\n"
                      b"Content-Type: application/json\r\nConnection: close\r\n"
                      b"Content-Length: " + str(len(body)).encode() + b"\r\n\r\n" + body)
            answer = b""
            while True:
                chunk = s.recv(4096)
                if not chunk:
                    break
                answer += chunk
            s.close()
            return int(answer.split(b" ")[1]), (time.monotonic() - t0) * 1e3

        held = []
        for a in range(attackers):
            held += hold(f"127.0.0.{2 + a}", per_address)
        time.sleep(2)
        attack_held = alive(held)
        first = [sign_in("127.0.1.1") for _ in range(signins)]
        crowd = []
        for a in range(many):
            crowd += hold(f"127.0.{2 + a // 250}.{2 + a % 250}", 4)
        time.sleep(2)  # the server has accepted (and refused or evicted) every connection
        second = [sign_in("127.0.1.2") for _ in range(signins)]
        result = {
            "attackers": attackers, "per_address": per_address,
            "attack_connections_held": attack_held, "attack_connections_tried": attackers * per_address,
            "signins_under_attack": [{"status": s, "ms": round(ms, 1)} for s, ms in first],
            "crowd_addresses": many, "held_after_crowd": alive(held + crowd),
            "signins_when_full": [{"status": s, "ms": round(ms, 1)} for s, ms in second],
        }
        for s in held + crowd:
            s.close()
        print(json.dumps(result))
    finally:
        server.terminate()
        server.wait(timeout=30)


if __name__ == "__main__":
    main()
