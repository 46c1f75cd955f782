# Shared by deploy/test.sh and deploy/demo.sh: Debian packages and the build. Source it.
#
# The packages the project needs today: core, tests, benchmarks, and the UDP channel (Asio from
# Boost, protobuf, OpenSSL), the control plane (gRPC, SQLite), the stations (OpenGL: GLFW for windows,
# EGL on Mesa for headless rendering; Xvfb and xdotool to test the window and its keys), libpng for
# screenshots, gnuplot for the study's figures, Dear ImGui for the stations' and monitors' HUD (its
# text in DejaVu Sans through FreeType),
# PostgreSQL (the shared store of a multi-node site: libpq, and the server the tests start),
# PyYAML for the Kubernetes manifests' check (deploy/k8s/check.py), the openssl command for the
# internal API's certificates (deploy/cluster_certs.sh), METIS for the FEM's sparse Cholesky.
# CLI11 splits every tool's command line (common/core/args.h).
# Glewlwyd (with sqlite3 and curl to set it up) is the OpenID Connect identity provider the
# dashboard's sign-in is tested against (deploy/oidc_provider.sh).
VSURG_PACKAGES=(
  cmake ninja-build g++ lld
  libeigen3-dev libmetis-dev nlohmann-json3-dev libcli11-dev
  libgtest-dev libbenchmark-dev
  libboost-dev libprotobuf-dev protobuf-compiler libssl-dev
  libgrpc++-dev protobuf-compiler-grpc libsqlite3-dev libpng-dev gnuplot-nox
  libglfw3-dev libegl-dev libgl-dev libopengl-dev libegl-mesa0 libgl1-mesa-dri xvfb xauth xdotool
  chromium chromium-driver python3-selenium libjs-chart.js nodejs zlib1g-dev
  libimgui-dev libfreetype-dev fonts-dejavu-core
  libassimp-dev libcgal-dev
  postgresql libpq-dev python3-yaml python3-prometheus-client openssl
  glewlwyd sqlite3 curl
)

# The fuzzers and the sanitizer builds (deploy/fuzz.sh, deploy/sanitize.sh): clang with libFuzzer's
# runtime, and llvm-symbolizer for readable reports. GCC's sanitizer runtimes come with g++.
VSURG_FUZZ_PACKAGES=(clang libclang-rt-14-dev llvm)

# The sanitizer build (clang, -O1, AddressSanitizer + UBSan, libFuzzer coverage) in build-asan/:
# deploy/sanitize.sh runs the tests from it, deploy/fuzz.sh the fuzz targets.
vsurg_configure_asan() {
  local root; root="$(vsurg_root)"
  CC=clang CXX=clang++ cmake -S "$root" -B "$root/build-asan" -G Ninja \
    -DCMAKE_BUILD_TYPE=RelWithDebInfo "-DCMAKE_CXX_FLAGS_RELWITHDEBINFO=-O1 -g1" \
    -DVSURG_BENCH=OFF -DVSURG_SANITIZE=ON -DVSURG_FUZZ=ON -DVSURG_WERROR=OFF >/dev/null
}

vsurg_root() { cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd; }

# Installs only the missing packages; needs root (or sudo) when something is missing.
vsurg_install_packages() { vsurg_install_packages_of VSURG_PACKAGES; }

# Same, for the list named by $1 (an array variable's name).
vsurg_install_packages_of() {
  local -n wanted="$1"
  local missing=() p
  for p in "${wanted[@]}"; do
    dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "ok installed" || missing+=("$p")
  done
  if [ ${#missing[@]} -eq 0 ]; then
    echo "vsurg: all ${#wanted[@]} Debian packages of $1 present"
    return 0
  fi
  echo "vsurg: installing ${missing[*]}"
  local sudo=""
  if [ "$(id -u)" -ne 0 ]; then
    command -v sudo >/dev/null || { echo "vsurg: need root to install: ${missing[*]}" >&2; return 1; }
    sudo="sudo"
  fi
  $sudo env DEBIAN_FRONTEND=noninteractive apt-get update -q
  $sudo env DEBIAN_FRONTEND=noninteractive apt-get install -y -q --no-install-recommends "${missing[@]}"
}

# The browser tests' npm packages (tests/e2e/package-lock.json: axe-core), installed from the
# npm registry with the lockfile's exact versions when missing.
vsurg_install_npm() {
  local root; root="$(vsurg_root)"
  if [ -f "$root/tests/e2e/node_modules/axe-core/axe.min.js" ]; then
    echo "vsurg: the browser tests' npm packages present"
    return 0
  fi
  npm ci --prefix "$root/tests/e2e" --no-audit --no-fund --loglevel=error
}

# Configures and builds into build/ with two jobs (the machine has two cores).
vsurg_build() {
  local root; root="$(vsurg_root)"
  cmake -S "$root" -B "$root/build" -G Ninja -DCMAKE_BUILD_TYPE=RelWithDebInfo "$@"
  cmake --build "$root/build" -j2
}
