# Sourced by the bench scripts that drive stations against one server of their own: in the current
# folder, a fresh store, a vsurg-server on loopback (its pid in $spid, its gRPC port in $PORT) and a
# trainee's token in t.tok. $B is the folder of the binaries.
$B/vsurg-server init --db vs.db > admin.out 2>/dev/null
$B/vsurg-server --db vs.db --listen 127.0.0.1:0 --udp-port 0 --ready-file ready.json 2>/dev/null & spid=$!
for _ in $(seq 100); do [ -s ready.json ] && break; sleep 0.1; done
PORT=$(python3 -c "import json;print(json.load(open('ready.json'))['grpc_port'])")
$B/vsurg-admin user-add --server 127.0.0.1:$PORT --token $(head -1 admin.out) --name ana --role trainee --issue-token | tail -1 > t.tok
