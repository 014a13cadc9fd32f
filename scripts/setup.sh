#!/usr/bin/env bash
# Create or update the local virtual environment and the Debian libraries the project needs.
# Idempotent: a second run installs only what is missing.
set -euo pipefail
cd "$(dirname "$0")/.."

# Debian packages: Open3D needs libusb and GL/EGL/X11 client libraries; the browser
# test of saved Meshcat pages needs chromium; graphviz's dot draws the station's diagram
# (docs/station.md, scripts/station_diagram.py).
debs=(libusb-1.0-0 libgl1 libegl1 libx11-6 libgomp1 graphviz)
if [ "${DRAKE_CONTINUUM_BROWSER:-1}" = "1" ]; then debs+=(chromium); fi
missing=()
if command -v dpkg >/dev/null 2>&1; then
  for p in "${debs[@]}"; do
    dpkg -s "$p" >/dev/null 2>&1 || missing+=("$p")
  done
fi
if [ ${#missing[@]} -gt 0 ]; then
  if [ "$(id -u)" = "0" ] && command -v apt-get >/dev/null 2>&1; then
    echo "setup: installing Debian packages: ${missing[*]}"
    export DEBIAN_FRONTEND=noninteractive
    apt-get update -qq >/dev/null
    apt-get install -y -qq --no-install-recommends "${missing[@]}" >/dev/null
  else
    echo "setup: please install these Debian packages (as root): apt-get install ${missing[*]}" >&2
    case " ${missing[*]} " in *" libusb-1.0-0 "*) exit 1;; esac
  fi
fi

py=${PYTHON:-python3}
if [ ! -x .venv/bin/python ]; then
  echo "setup: creating .venv with $($py --version)"
  "$py" -m venv .venv
fi
stamp=.venv/.installed
if [ ! -f "$stamp" ] || [ pyproject.toml -nt "$stamp" ]; then
  echo "setup: installing Python packages into .venv (first time takes a few minutes)"
  .venv/bin/python -m pip install -q --upgrade pip
  # the test extra, and the cluster extra: the suite runs a collection on a local Dask cluster
  .venv/bin/python -m pip install -q -e ".[test,cluster]"
  touch "$stamp"
fi

# numba compiles each kernel on first use (1-12 s a layout, in every worker of a first
# collection at once) and caches it on disk: compile them all here, once after each install
# or change of a module with kernels (one that imports numba), so that no run pays it.
kstamp=.venv/.kernels-compiled
changed=$(grep -rl --include='*.py' '^from numba import' drake_continuum \
  | while read -r f; do [ ! -f "$kstamp" ] || [ "$f" -nt "$kstamp" ] && echo "$f"; done || true)
if [ ! -f "$kstamp" ] || [ -n "$changed" ] || [ "$stamp" -nt "$kstamp" ]; then
  echo "setup: compiling the numba kernels (about 30 s the first time)"
  .venv/bin/python -m drake_continuum.kernels
  touch "$kstamp"
fi
