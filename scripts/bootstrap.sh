#!/usr/bin/env bash
# One-time set-up shared by `make demo`, `make test` and `make docs`: create or reuse .venv,
# install the package with its test and docs extras into it, and make sure drjit's LLVM backend renders (drjit 1.5 needs libLLVM >= 16).
# Re-running is cheap: each step is skipped when already done.
set -euo pipefail
cd "$(dirname "$0")/.."
PY=${PYTHON:-python3}
VENV=.venv
STAMP=$VENV/.pacam-installed

as_root() { [ "$(id -u)" = 0 ]; }
apt_install() {  # apt_install PKG... ; returns non-zero if not root or apt fails
  as_root && command -v apt-get >/dev/null || return 1
  if [ ! -f /tmp/.pacam-apt-updated ]; then
    apt-get -o DPkg::Lock::Timeout=300 update -qq && touch /tmp/.pacam-apt-updated
  fi
  # another apt/dpkg (unattended upgrades at boot) may hold the lock: wait for it, 5 min at most
  DEBIAN_FRONTEND=noninteractive apt-get -o DPkg::Lock::Timeout=300 install -y -qq "$@" >/dev/null
}

# 1. Python >= 3.10
if ! "$PY" -c 'import sys; sys.exit(sys.version_info < (3, 10))'; then
  echo "error: pacam_render needs Python >= 3.10; $PY is $("$PY" --version 2>&1)." >&2
  echo "       Set PYTHON=/path/to/python3.x and re-run." >&2
  exit 1
fi

# 2. The virtual environment (Debian's python3 needs python3-venv for ensurepip).
if [ ! -x $VENV/bin/python ]; then
  if ! "$PY" -m venv $VENV 2>/dev/null; then
    rm -rf $VENV
    ver=$("$PY" -c 'import sys; print(f"{sys.version_info[0]}.{sys.version_info[1]}")')
    echo "python venv support missing; installing python$ver-venv ..."
    apt_install "python$ver-venv" || apt_install python3-venv || {
      echo "error: cannot create a virtual environment. Run: sudo apt-get install -y python3-venv" >&2
      exit 1; }
    "$PY" -m venv $VENV
  fi
fi

# 3. The package (re-installed when pyproject.toml changes).
if [ ! -f $STAMP ] || [ pyproject.toml -nt $STAMP ]; then
  echo "installing pacam_render into $VENV ..."
  $VENV/bin/python -m pip install -q --upgrade pip 2>&1 | grep -v 'is ignored' || true
  $VENV/bin/python -m pip install -q -e '.[test,docs]' 2>&1 | grep -v 'is ignored' || true
  $VENV/bin/python -c 'import pacam_render, mitsuba, drjit, sphinx, myst_nb' || {
    echo "error: installing pacam_render into $VENV failed (see pip's output above)" >&2; exit 1; }
  touch $STAMP
fi

# 4. drjit's LLVM backend. A broken libLLVM aborts the renderer, so check in a subprocess.
if ! $VENV/bin/python -m pacam_render.render.backend --check >/dev/null 2>&1; then
  echo "drjit's LLVM backend cannot render here (it needs libLLVM >= 16)."
  for pkg in libllvm19 libllvm18 libllvm17 libllvm16; do
    if apt_install "$pkg" 2>/dev/null && $VENV/bin/python -m pacam_render.render.backend --check >/dev/null 2>&1; then
      echo "installed $pkg: LLVM backend OK"; break
    fi
  done
  if ! $VENV/bin/python -m pacam_render.render.backend --check >/dev/null 2>&1; then
    echo "WARNING: still no working LLVM backend; rendering will use the slow scalar variant." >&2
    echo "         Fix it with:  sudo apt-get install -y libllvm19" >&2
  fi
fi
