# Shared by the reference scripts (sourced, not run). Defines:
#   ROOT, RAYPROOF (built on demand), TOOLS (cache for the Mitsuba venv and libLLVM),
#   parse_ref_args DEFAULT_FILE (SCENE [--width W] [--grid N] [-o OUT]); the manifest entries
#   are written by `rayproof reference`, which the scripts run.
set -euo pipefail
ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
TOOLS="${RAYPROOF_TOOLS:-$HOME/.cache/rayproof}"
RAYPROOF="$ROOT/target/release/rayproof"
( cd "$ROOT" && cargo build --release --quiet )

# The references are made at 256 pixels wide (scene aspect) with an 8x8 sub-pixel grid.
parse_ref_args() {
  local default="$1"; shift
  SCENE=""; WIDTH=256; GRID=8; OUT=""; VARIANT=""
  while [ $# -gt 0 ]; do
    case "$1" in
      --width) WIDTH="$2"; shift 2 ;;
      --grid) GRID="$2"; shift 2 ;;
      -o) OUT="$2"; shift 2 ;;
      --variant) VARIANT="$2"; shift 2 ;;
      -*) echo "error: unknown option $1" >&2; exit 2 ;;
      *) SCENE="$1"; shift ;;
    esac
  done
  [ -n "$SCENE" ] && [ -f "$SCENE" ] && SCENE="$(cd "$(dirname "$SCENE")" && pwd)/$(basename "$SCENE")"
  [ -f "$SCENE" ] || { echo "error: give a scene file (reference/scenes/NAME.toml)" >&2; exit 2; }
  NAME="$(basename "$SCENE" .toml)"
  MANIFEST=""
  if [ -z "$OUT" ]; then
    # reference/scenes/NAME.toml -> reference/NAME/; elsewhere DIR/NAME.toml -> DIR/NAME/
    local dir; dir="$(dirname "$SCENE")"
    if [ "$(basename "$dir")" = scenes ]; then dir="$ROOT/reference"; fi
    local out="${REF_DIR:-$dir/$NAME}"   # REF_DIR: another directory for this scene's references
    mkdir -p "$out"
    OUT="$out/$default"
    MANIFEST="$out/manifest.json"
  else
    OUT="$(cd "$(dirname "$OUT")" && pwd)/$(basename "$OUT")"
  fi
}
