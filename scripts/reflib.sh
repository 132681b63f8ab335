# Shared by the reference scripts (sourced, not run). Defines:
#   ROOT, RAYPROOF (built on demand), TOOLS (cache for the Mitsuba venv and libLLVM), mitsuba_setup,
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

# mitsuba_setup [VARIANT]: sets MITSUBA_PY (a venv's python with mitsuba and numpy, made on first
# use in $TOOLS/mitsuba-venv), MITSUBA_VARIANT (VARIANT, default llvm_ad_rgb, or scalar_rgb when
# libLLVM 19 cannot be had) and exports DRJIT_LIBLLVM_PATH for the llvm variant.
mitsuba_setup() {
  MITSUBA_VARIANT="${1:-llvm_ad_rgb}"
  MITSUBA_PY="$TOOLS/mitsuba-venv/bin/python"
  # The venv with Mitsuba
  if ! "$MITSUBA_PY" -c "import mitsuba, numpy" 2>/dev/null; then
    echo "setting up $TOOLS/mitsuba-venv (pip install mitsuba numpy)" >&2
    mkdir -p "$TOOLS"
    python3 -m venv "$TOOLS/mitsuba-venv"
    "$TOOLS/mitsuba-venv/bin/pip" install --quiet mitsuba numpy
  fi
  # libLLVM 19 for the llvm variant (Debian's default LLVM aborts with "Cannot select fmaximum")
  local llvm
  llvm="$(find "$TOOLS/llvm19" -name 'libLLVM.so.19*' 2>/dev/null | head -n1 || true)"
  if [ -z "$llvm" ]; then
    echo "fetching libLLVM 19 (apt-get download libllvm19) into $TOOLS/llvm19" >&2
    ( cd "$TOOLS" && apt-get download libllvm19 >/dev/null 2>&1 && dpkg -x libllvm19_*.deb llvm19 ) || true
    llvm="$(find "$TOOLS/llvm19" -name 'libLLVM.so.19*' 2>/dev/null | head -n1 || true)"
  fi
  if [ -n "$llvm" ]; then
    export DRJIT_LIBLLVM_PATH="$llvm"
  elif [ "$MITSUBA_VARIANT" != scalar_rgb ]; then
    echo "warning: no libLLVM 19; falling back to the scalar_rgb variant (slow)" >&2
    MITSUBA_VARIANT=scalar_rgb
  fi
}
