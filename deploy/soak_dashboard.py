#!/usr/bin/env python3
"""One instructor's dashboard for deploy/soak.sh, as the pages use the HTTP API (stdlib only).

    soak_dashboard.py PORT TOKEN SECONDS OUT.json

Signs in with the token (cookie + CSRF token, as the sign-in page), follows the live page's
event stream and one running session's event stream (with its surface), and every 5 s loads
the live page, the sessions list and the session list API, as a page reload would. It counts
frames and bytes per minute, the requests' latency, and every stream that broke (a stream that
ends or stops sending for 5 s while its session runs is a failure; the page would reconnect,
and so does this client). Writes OUT.json at the end; exit 0 unless signing in failed.
"""
import http.client
import json
import sys
import threading
import time

port, token, seconds, out_path = int(sys.argv[1]), sys.argv[2], float(sys.argv[3]), sys.argv[4]
start = time.monotonic()
lock = threading.Lock()
stats = {"frames": {}, "bytes": {}, "stream_breaks": [], "request_errors": [], "request_ms": []}


def minute():
    return int((time.monotonic() - start) // 60)


def note(kind, value):
    with lock:
        if kind in ("frames", "bytes"):
            stats[kind][minute()] = stats[kind].get(minute(), 0) + value
        else:
            stats[kind].append(value)


connection = None  # one kept-alive connection for pages and API calls, as a browser keeps


def request(method, path, cookie, csrf=None, body=None):
    global connection
    headers = {"Cookie": cookie} if cookie else {}
    if body is not None:
        headers["Content-Type"] = "application/json"
        if csrf:
            headers["X-CSRF-Token"] = csrf
    t0 = time.monotonic()
    for attempt in (0, 1):  # a kept-alive connection the server closed is opened again once
        if connection is None:
            connection = http.client.HTTPConnection("127.0.0.1", port, timeout=10)
        try:
            connection.request(method, path, body=json.dumps(body) if body is not None else None,
                               headers=headers)
            r = connection.getresponse()
            data = r.read()
            break
        except (http.client.RemoteDisconnected, ConnectionResetError, BrokenPipeError):
            connection.close()
            connection = None
            if attempt:
                raise
    return r.status, r.getheader("Set-Cookie"), data, (time.monotonic() - t0) * 1000


def follow(path, cookie, name):
    """An EventSource: reconnects after a break, as the browser does (retry 2 s)."""
    while time.monotonic() - start < seconds:
        try:
            c = http.client.HTTPConnection("127.0.0.1", port, timeout=5)
            c.request("GET", path, headers={"Cookie": cookie})
            r = c.getresponse()
            if r.status != 200:
                note("stream_breaks", f"{name}: status {r.status} at {time.monotonic() - start:.0f} s")
                time.sleep(2)
                continue
            buf = b""
            while time.monotonic() - start < seconds:
                chunk = r.fp.read1(65536)  # the socket's timeout (5 s) counts as a break
                if not chunk:
                    raise ConnectionError("the server ended the stream")
                note("bytes", len(chunk))
                buf += chunk
                while b"\n\n" in buf:
                    event, buf = buf.split(b"\n\n", 1)
                    if event.startswith(b"event: ended"):
                        return  # the session ended: the page shows its results
                    if event.startswith(b"data: "):
                        note("frames", 1)
            c.close()
        except Exception as e:  # noqa: BLE001 - every break is counted, then reconnected
            if time.monotonic() - start < seconds:
                note("stream_breaks", f"{name}: {e} at {time.monotonic() - start:.0f} s")
                time.sleep(2)


status, set_cookie, body, _ = request("POST", "/api/v1/signin", None, body={"token": token})
if status != 200 or not set_cookie:
    print(f"soak_dashboard: sign-in failed ({status}): {body[:200]!r}", file=sys.stderr)
    sys.exit(2)
cookie = set_cookie.split(";", 1)[0]
csrf = json.loads(body)["csrf"]
live = json.loads(request("GET", "/api/v1/sessions?live=1", cookie)[2])["sessions"]
running = [s["id"] for s in live if s["state"] == "running"]
threads = [threading.Thread(target=follow, args=("/api/v1/live/events", cookie, "live"), daemon=True)]
if running:
    session = running[len(running) // 2]
    threads.append(threading.Thread(
        target=follow, args=(f"/api/v1/sessions/{session}/events", cookie, f"session {session}"),
        daemon=True))
for t in threads:
    t.start()
while time.monotonic() - start < seconds:
    for path in ("/live", "/api/v1/sessions?live=1", "/api/v1/sessions"):
        try:
            status, _, _, ms = request("GET", path, cookie)
            note("request_ms", ms)  # one per answered request
            if status != 200:
                note("request_errors", f"{path}: {status}")
        except Exception as e:  # noqa: BLE001
            note("request_errors", f"{path}: {e}")
    time.sleep(5)
for t in threads:
    t.join(timeout=10)
with lock:
    ms = sorted(stats["request_ms"])
    summary = {
        "streams": len(threads),
        "frames_per_minute": [stats["frames"].get(m, 0) for m in range(int(seconds // 60) + 1)],
        "kbytes_per_minute": [round(stats["bytes"].get(m, 0) / 1024) for m in range(int(seconds // 60) + 1)],
        "stream_breaks": stats["stream_breaks"],
        "requests": len(ms),
        "request_errors": stats["request_errors"],
        "request_ms_p50": ms[len(ms) // 2] if ms else None,
        "request_ms_p99": ms[min(len(ms) - 1, int(len(ms) * 0.99))] if ms else None,
    }
json.dump(summary, open(out_path, "w"))
