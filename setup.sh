#!/usr/bin/env bash
# Creates ./.venv and installs fitode into it, with the test tools and Ray (for
# `fitode batch --executor ray` and its test). torch comes first, pinned to the CPU build this
# machine's package index carries; an unpinned torch would pull gigabytes of CUDA.
set -euo pipefail
cd "$(dirname "$0")"
PY=${PYTHON:-python3}
[ -x .venv/bin/python ] || "$PY" -m venv .venv
.venv/bin/python -m pip install -q --disable-pip-version-check torch==2.13.0
.venv/bin/python -m pip install -q --disable-pip-version-check -e ".[dev,ray]"
