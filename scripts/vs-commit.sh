#!/usr/bin/env bash
# `railgrip run` on the bundled archive, this checkout against an earlier commit, in the same
# session: both release binaries run in turn (A B A B ...), estimates reused (the training
# stage and the report dominate), and the median wall and CPU seconds of each with the
# pair-by-pair ratio. Prints the CPU it ran on.
#
#   scripts/vs-commit.sh COMMIT [RUNS]      # RUNS pairs, default 5
#
# COMMIT is built in a git worktree with a target directory of its own (target/vs-<commit>:
# the first call compiles every dependency there; later calls reuse it). Needs GNU time
# (/usr/bin/time) and python3.
set -euo pipefail
base=${1:?usage: scripts/vs-commit.sh COMMIT [RUNS]}
runs=${2:-5}
[ "$runs" -ge 1 ] 2>/dev/null || { echo "RUNS must be a whole number >= 1" >&2; exit 2; }
root=$(git rev-parse --show-toplevel)
cd "$root"
short=$(git rev-parse --short "$base")
tree="$root/target/vs-$short-tree"
git worktree prune
[ -d "$tree" ] || git worktree add --detach "$tree" "$base" >/dev/null
echo "building $short (worktree $tree) and this checkout, release" >&2
(cd "$tree" && CARGO_TARGET_DIR="$root/target/vs-$short" cargo build --release -q)
cargo build --release -q
old="$root/target/vs-$short/release/railgrip"
new="$root/target/release/railgrip"
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
# One run of BIN into OUT, timed into $work/times as LABEL; exit 0 or 3 (runs failed but
# models written) is a run, anything else stops the script.
timed() {
  local label=$1 bin=$2 out=$3 rc=0
  /usr/bin/time -f "$label %e %U %S" -a -o "$work/times" "$bin" run --out "$out" >/dev/null 2>"$work/err" || rc=$?
  if [ "$rc" -eq 3 ]; then
    echo "$label: railgrip run exited 3 (some runs failed; this timing did less work)" >&2
  elif [ "$rc" -ne 0 ]; then
    echo "$label: railgrip run exited $rc:" >&2
    cat "$work/err" >&2
    exit 1
  fi
}
# One warm-up each (writes the estimates both then reuse), not counted.
timed warm "$old" "$work/old"
timed warm "$new" "$work/new"
for _ in $(seq "$runs"); do
  timed old "$old" "$work/old"
  timed new "$new" "$work/new"
done
grep -m1 "model name" /proc/cpuinfo | sed 's/.*: /cpu: /' || true
echo "cores: $(nproc); vector width: $(grep -o -m1 'avx512f' /proc/cpuinfo || grep -o -m1 'avx2' /proc/cpuinfo || echo none)"
python3 - "$work/times" "$short" <<'EOF'
import statistics, sys
rows = [l.split() for l in open(sys.argv[1]) if l.split() and l.split()[0] in ("old", "new")]
old = [(float(r[1]), float(r[2]) + float(r[3])) for r in rows if r[0] == "old"]
new = [(float(r[1]), float(r[2]) + float(r[3])) for r in rows if r[0] == "new"]
med = statistics.median
print(f"{sys.argv[2]}: wall {med(w for w, _ in old):.2f} s, cpu {med(c for _, c in old):.2f} s")
print(f"this checkout: wall {med(w for w, _ in new):.2f} s, cpu {med(c for _, c in new):.2f} s")
ratios = sorted(n[0] / o[0] for n, o in zip(new, old))
print(f"wall ratio this/{sys.argv[2]}, pair by pair: median {med(ratios):.2f} (min {ratios[0]:.2f}, max {ratios[-1]:.2f}, {len(ratios)} pairs)")
EOF
