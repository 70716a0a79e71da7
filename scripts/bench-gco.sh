#!/usr/bin/env bash
# Motif's alpha-expansion next to GCO 3.0 (Veksler & Delong's reference implementation, through
# the gco-wrapper package from PyPI) on the mrf_grid_v1 problems of issue 4's solver table.
#
#   scripts/bench-gco.sh [--large] [--rounds N]
#
# Builds the release binary, installs gco-wrapper and numpy into target/gco-venv (once), writes
# the problems with `motif mrf generate` and solves each one with GCO and with Motif (1 thread and
# all threads), interleaving the runs so that both see the same machine load. Prints energies,
# median times and the ratios Motif / GCO. Not part of the tests (it needs PyPI and takes minutes).
set -euo pipefail
repo="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
target="${CARGO_TARGET_DIR:-$repo/target}"
venv="$target/gco-venv"
(cd "$repo" && cargo build --release --quiet --bin motif)
if [ ! -x "$venv/bin/python" ] || ! "$venv/bin/python" -c "import gco" 2>/dev/null; then
    echo "bench-gco: installing gco-wrapper and numpy into $venv" >&2
    python3 -m venv "$venv"
    "$venv/bin/pip" install --quiet gco-wrapper numpy
fi
exec "$venv/bin/python" "$repo/scripts/bench_gco.py" --motif "$target/release/motif" "$@"
