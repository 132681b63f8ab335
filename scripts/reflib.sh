# Shared by the reference scripts (sourced, not run). Defines:
#   ROOT, RAYPROOF (built on demand), TOOLS (cache for the Mitsuba venv and libLLVM),
#   parse_ref_args DEFAULT_FILE (SCENE [--width W] [--grid N] [-o OUT]) and record_manifest.
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

# A command line as recorded: paths under the repository shown relative to it.
shown() { local out=() a; for a in "$@"; do out+=("${a#"$ROOT"/}"); done; echo "${out[*]}"; }

# record_manifest FILE RENDERER VERSION SECONDS COMMAND...: one entry of reference/NAME/manifest.json
record_manifest() {
  [ -n "$MANIFEST" ] || return 0
  local file="$1" renderer="$2" version="$3" secs="$4"; shift 4
  ROOT="$ROOT" python3 - "$MANIFEST" "$file" "$renderer" "$version" "$secs" "$SCENE" "$WIDTH" "$GRID" "$@" <<'PY'
import datetime, hashlib, json, os, sys
manifest, file, renderer, version, secs, scene, width, grid = sys.argv[1:9]
commands = sys.argv[9:]
sha = lambda p: hashlib.sha256(open(p, "rb").read()).hexdigest()
root = os.environ["ROOT"]
m = json.load(open(manifest)) if os.path.exists(manifest) else {}
m.setdefault("scene", os.path.relpath(os.path.abspath(scene), root))
m.setdefault("files", {})
m["files"][os.path.basename(file)] = {
    "renderer": renderer,
    "version": version,
    "commands": commands,
    "width": int(width),
    "grid": int(grid),
    "samples_per_pixel": int(grid) ** 2,
    "date": datetime.datetime.now(datetime.timezone.utc).strftime("%Y-%m-%dT%H:%M:%SZ"),
    "seconds": round(float(secs), 2),
    "scene_sha256": sha(scene),
    "sha256": sha(file),
}
m["files"] = dict(sorted(m["files"].items()))
tmp = manifest + ".tmp"
with open(tmp, "w") as f:
    json.dump(m, f, indent=2)
    f.write("\n")
os.replace(tmp, manifest)
PY
}
