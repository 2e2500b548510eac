#!/usr/bin/env bash
# Regenerate requirements.lock: the exact versions a fresh .venv gets from pyproject.toml's ranges,
# with every extra the Makefile installs. Run as `make lock`; review the diff, run `make test`
# (pinned outputs may move with numpy/numba/scipy versions), commit both.
set -euo pipefail
cd "$(dirname "$0")/.."
PYTHON=${PYTHON:-python3}
EXTRAS=${EXTRAS:-plot,test,dask,denoise,aedat4,learn}
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT
"$PYTHON" -m venv "$tmp/venv"
"$tmp/venv/bin/python" -m pip install -q --upgrade pip
"$tmp/venv/bin/python" -m pip install -q -e ".[$EXTRAS]"
{
    echo "# Exact versions of every package of the .venv that 'make demo' and 'make test' build"
    echo "# (pyproject.toml's ranges with the extras [$EXTRAS], resolved on $(date -u +%Y-%m-%d)"
    echo "# with $("$tmp/venv/bin/python" --version), $(uname -m)). Regenerate: make lock"
    "$tmp/venv/bin/python" -m pip freeze --all --exclude-editable | grep -v -i '^gevsim==' | LC_ALL=C sort -f
} > requirements.lock.tmp
mv requirements.lock.tmp requirements.lock
echo "wrote requirements.lock ($(grep -c '==' requirements.lock) packages)"
