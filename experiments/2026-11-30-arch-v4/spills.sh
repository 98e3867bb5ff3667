#!/usr/bin/env bash
# Counts, in a dem-bench binary, the instructions of the plain scene's contact kernel
# (run_kernel<ContactKernel<Hertz, MindlinHistory, epsd2, 0, true, false>>) and those among them with a
# vector register and a stack operand (spills and reloads), and the binary's instructions on zmm
# (512-bit) registers, in all and in that kernel.
#   bash spills.sh DEM_BENCH...
set -euo pipefail
kernel='run_kernel<sandcell::(anonymous namespace)::ContactKernel<sandcell::Hertz, sandcell::MindlinHistory, (sandcell::RollingModel)1, 0, true, false> >'
for bench in "$@"; do
  objdump -d --no-show-raw-insn -C "$bench" | awk -v k="$kernel" -v b="$bench" '
    /^[0-9a-f]+ </ { f = index($0, k) > 0; next }
    /\t/ { if ($0 ~ /zmm/) zall++
           if (f) { n++; if ($0 ~ /\(%rsp\)|\(%rbp\)/ && $0 ~ /[xyz]mm/) s++; if ($0 ~ /zmm/) z++ } }
    END { printf "%s: kernel %d instructions, %d vector stack operands, %d on zmm; zmm in the binary %d\n", b, n, s, z, zall }'
done
