# The shell scripts' common start, sourced first (`source "$(dirname "$0")/lib.sh"`): strict
# mode, the repository root as the working directory, and helpers for the release CLI.
set -euo pipefail
cd "$(dirname "${BASH_SOURCE[0]}")/.."

# Sets `bin` to the release CLI, building it first; SOFTSHADOW_BIN names an already built one
# instead (nothing is built then).
release_cli() {
  bin=${SOFTSHADOW_BIN:-${CARGO_TARGET_DIR:-target}/release/softshadow}
  [ -n "${SOFTSHADOW_BIN:-}" ] || cargo build --release -q -p softshadow-cli
}

# A table script's start: `out` set to the folder $1 (made if missing), `bin` to the release CLI.
table_setup() {
  out=$1
  mkdir -p "$out"
  release_cli
}

# For the scene file $1: `name` set to its name, `ref` to its ray-traced reference in `out`
# (its default, 1024 spp), rendered first unless there already (a cache the table scripts with
# the same OUT_DIR share).
with_reference() {
  name=$(basename "$1" .toml)
  ref="$out/$name-reference.exr"
  [ -f "$ref" ] || $bin render "$1" --algo reference --out "$ref" >/dev/null
}

# Prints a markdown table's header: a row of the column names given, then the separator row.
table_header() {
  local row="|" sep="|" column
  for column in "$@"; do
    row+=" $column |"
    sep+="---|"
  done
  echo "$row"
  echo "$sep"
}
