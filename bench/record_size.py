#!/usr/bin/python3
"""The size of a session's record (server/session/trace_recorder.h) for a scene, and what its
surface frames would take in the encodings it could have used, from the same record in one run:
plain base64 of every frame, each frame deflated alone, and what is sent (one deflate stream of
each frame's difference from the one before). Runs a real vsurg-server and a replay station.

    bench/record_size.py BUILD_BIN_DIR SCENES_DIR SCENE [STYLE]
"""
import base64, json, os, shutil, subprocess, sys, tempfile, time, urllib.request, zlib

BIN, SCENES, SCENE = sys.argv[1], sys.argv[2], sys.argv[3]
STYLE = sys.argv[4] if len(sys.argv) > 4 else "good"
env = dict(os.environ, VSURG_SCENES=SCENES)
tmp = tempfile.mkdtemp(prefix="vsurg_record_")
db, ready = os.path.join(tmp, "v.db"), os.path.join(tmp, "ready.json")
admin = subprocess.run([f"{BIN}/vsurg-server", "init", "--db", db], capture_output=True, text=True,
                       env=env, check=True).stdout.strip()
server = subprocess.Popen([f"{BIN}/vsurg-server", "--db", db, "--listen", "127.0.0.1:0", "--udp-port", "0",
                           "--http", "127.0.0.1:0", "--ready-file", ready], env=env, stderr=subprocess.DEVNULL)
try:
    while not (os.path.exists(ready) and os.path.getsize(ready)):
        time.sleep(0.1)
    ports = json.load(open(ready))

    def api(method, path, token, body=None):
        r = urllib.request.Request(f"http://127.0.0.1:{ports['http_port']}/api/v1{path}", method=method)
        r.add_header("Authorization", "Bearer " + token)
        data = None
        if body is not None:
            r.add_header("Content-Type", "application/json")
            data = json.dumps(body).encode()
        with urllib.request.urlopen(r, data) as x:
            text = x.read()
            return json.loads(text) if text else None
    api("POST", "/users", admin, {"name": "t", "role": "trainee", "group": "g"})
    token = api("POST", "/users/t/token", admin, {})["token"]
    trajectory = os.path.join(tmp, "t.csv")
    subprocess.run([f"{BIN}/vsurg-sim", "trainee", "--scene", SCENE, "--style", STYLE, "--out", trajectory],
                   check=True, capture_output=True, env=env)
    session = api("POST", "/sessions", admin, {"trainee": "t", "scene": SCENE})["session"]["id"]
    subprocess.run([f"{BIN}/vsurg-station", "--server", f"127.0.0.1:{ports['grpc_port']}", "--token", token,
                    "--join", str(session), "--scene", SCENE, "--device", "replay", "--trajectory", trajectory,
                    "--headless", "--width", "160", "--height", "100", "--fps", "4", "--quality", "low",
                    "--realtime-priority", "0"], capture_output=True, env=env, check=True)
    record = api("GET", f"/sessions/{session}/trace", admin)
    f = record["frames"]
    n, count = 6 * f["vertices"], len(f["time_s"])
    diffs = zlib.decompress(base64.b64decode(f["deflated"]))
    frames, previous = [], bytearray(n)
    for k in range(count):  # the running sum of the differences, modulo 2^16
        d = diffs[k * n:(k + 1) * n]
        cur = bytearray(n)
        for i in range(0, n, 2):
            v = (previous[i] | previous[i + 1] << 8) + (d[i] | d[i + 1] << 8)
            cur[i], cur[i + 1] = v & 0xff, (v >> 8) & 0xff
        frames.append(bytes(cur))
        previous = cur
    print(f"{SCENE} ({STYLE}): {len(json.dumps(record)) / 1e3:.0f} kB record, {f['vertices']} vertices, "
          f"{count} frames over {f['time_s'][-1] - f['time_s'][0]:.1f} s, "
          f"{len(record['series']['time_s'])} samples")
    print(f"  frames as plain base64:          {sum(len(base64.b64encode(x)) for x in frames) / 1e3:8.1f} kB")
    print(f"  each frame deflated, base64:     {sum(len(base64.b64encode(zlib.compress(x, 6))) for x in frames) / 1e3:8.1f} kB")
    print(f"  differences deflated (sent):     {len(f['deflated']) / 1e3:8.1f} kB")
finally:
    server.terminate()
    server.wait()
    shutil.rmtree(tmp, ignore_errors=True)
