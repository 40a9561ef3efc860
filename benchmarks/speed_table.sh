#!/bin/sh
# The speed figures of README's "Performance" and docs/performance.md in one run, on one
# machine, each printed under the command that makes it (about 20 minutes on 2 cores):
#
#   sh benchmarks/speed_table.sh 2>&1 | tee speed.txt
#
# 1. 10^4 and 10^5 spheres, each with its own material, 512x384, 1 spp: the parse,
#    translation, load and render stages, the whole `raymitsuba render` process and
#    POV-Ray 3.7's on the same scene (scale_bench.py; POV-Ray is skipped if not installed).
# 2. The parser's throughput, and on the scale ladder's simple lines against 10^6 lines/s.
# 3. `--aa` against 1 spp, and against a 256-spp reference and a 987-spp truth, on the
#    benchmark's reflective scene, scenes/aa_showcase.ray (not the benchmark's), a generated
#    fine-detail scene and four gallery scenes.
# 4. Depth 64 at 1024x768 against POV-Ray and the exact tree.
set -e
cd "$(dirname "$0")/.."
run() {
    printf '\n$ %s\n' "$*"
    "$@"
}
run ./dev bench --scale --family spheres --min-size 10000 --repeat 3
run ./dev python benchmarks/parse_bench.py --max-exponent 5 --repeat 5
run ./dev bench --only aa
run ./dev bench --only deep
