#!/usr/bin/env bash
# Criterion medians of this checkout against another revision, measured in one
# session: builds a worktree of REV beside this one, runs each bench binary of
# both alternately (ROUNDS rounds, on one core), and prints every benchmark's
# best median of both and their ratio (this / REV), then the geometric mean.
#
#   tools/bench_against.sh 3e30b16 forward            # every forward benchmark
#   tools/bench_against.sh 3e30b16 robot 'actuated'   # a filter, criterion's
#
# Nothing else should run meanwhile: the ratios move by a few per cent with the
# machine's load. (A development tool; `make bench` gives the README's medians.)
set -euo pipefail
rev=${1:?usage: tools/bench_against.sh REV BENCH [FILTER] [ROUNDS]}
bench=${2:?usage: tools/bench_against.sh REV BENCH [FILTER] [ROUNDS]}
filter=${3:-}
rounds=${4:-2}
here=$(git rev-parse --show-toplevel)
base=${BENCH_BASE_DIR:-$here/../bench-base-$rev}
out=$(mktemp -d)
if [ ! -d "$base" ]; then
  git -C "$here" worktree add -f "$base" "$rev" >/dev/null
fi
for tree in "$here" "$base"; do
  (cd "$tree" && cargo bench --bench "$bench" --no-run 2>&1 | tail -1)
done
binary() { ls -t "$1"/target/release/deps/"$bench"-* | grep -v '\.d$' | head -1; }
for round in $(seq 1 "$rounds"); do
  for tree in here base; do
    dir=$here; [ "$tree" = base ] && dir=$base
    (cd "$dir" && taskset -c 1 "$(binary "$dir")" --bench --warm-up-time 0.5 \
      --measurement-time 1.5 --noplot ${filter:+"$filter"}) > "$out/${tree}_$round.txt" 2>&1
  done
done
python3 - "$out" <<'PY'
import glob, math, re, sys
units = {"ns": 1e-9, "µs": 1e-6, "us": 1e-6, "ms": 1e-3, "s": 1.0}
def medians(path):
    found, name = {}, None
    for line in open(path):
        head = re.match(r"^(\S+)\s*(time:.*)?$", line.rstrip())
        if head and not line.startswith(("Benchmarking", "Found", "Warning")):
            name = head.group(1)
        m = re.search(r"time:\s+\[\S+ \S+ (\S+) (\S+) \S+ \S+\]", line)
        if m and name:
            found[name] = float(m.group(1)) * units[m.group(2)]
    return found
best = {}
for tree in ("here", "base"):
    best[tree] = {}
    for path in glob.glob(f"{sys.argv[1]}/{tree}_*.txt"):
        for k, v in medians(path).items():
            best[tree][k] = min(best[tree].get(k, math.inf), v)
ratios = []
for k, b in best["base"].items():
    if k in best["here"]:
        h = best["here"][k]
        ratios.append(h / b)
        print(f"{k:60s} {b * 1e6:11.2f} us {h * 1e6:11.2f} us  {h / b:.3f}")
if ratios:
    mean = math.exp(sum(map(math.log, ratios)) / len(ratios))
    print(f"geometric mean (this / base) {mean:.3f} over {len(ratios)} benchmarks")
PY
