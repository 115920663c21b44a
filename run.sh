#!/usr/bin/env bash
# The two commands of the README:
#   bash run.sh all    install what is needed, regenerate every figure, table and REPORT.md
#   bash run.sh test   install what is needed, run the test suite
set -euo pipefail
cd "$(dirname "$0")"

setup() {
  local stamp=.venv/.installed-$(sha256sum requirements.lock pyproject.toml | sha256sum | cut -c1-16)
  if [ ! -x .venv/bin/python ]; then
    echo "creating .venv" >&2
    python3 -m venv .venv
  fi
  if [ ! -f "$stamp" ]; then
    echo "installing pinned dependencies (requirements.lock)" >&2
    .venv/bin/python -m pip install --quiet --upgrade "pip==26.3" >&2
    .venv/bin/python -m pip install --quiet -r requirements.lock >&2
    .venv/bin/python -m pip install --quiet --no-deps -e . >&2
    .venv/bin/python -m pip install --quiet "pytest==9.2.0" "pytest-xdist==3.8.0" "execnet==2.1.2" \
      "ruff==0.17.6" >&2
    rm -f .venv/.installed-*
    touch "$stamp"
  fi
}

case "${1:-}" in
  all)  setup; shift; exec .venv/bin/replicate-all "$@" ;;
  # one pytest worker per CPU (pytest-xdist), idle workers taking tests from busy ones;
  # `bash run.sh test -n 0` runs them in one process; the 15 slowest tests are listed at the end
  test) setup; shift; exec .venv/bin/python -m pytest -n auto --dist worksteal --durations=15 "$@" ;;
  setup) setup ;;
  *) echo "usage: bash run.sh all|test|setup [args]" >&2; exit 2 ;;
esac
