#!/usr/bin/env bash
# Builds the two dem-bench variants of this experiment from the repository at hand (run from its
# root): a profile-guided build (GCC -fprofile-generate, a training run, -fprofile-use) and a
# link-time-optimized one (CMAKE_INTERPROCEDURAL_OPTIMIZATION). Both keep the project's own flags
# (SANDCELL_ARCH=auto, -mno-fma, -ffp-contract=off), so their results must be the same bits.
#   bash experiments/2026-11-30-pgo-lto/build.sh WORK
# leaves WORK/bin/dem-bench-pgo and WORK/bin/dem-bench-lto.
set -euo pipefail
work=$(realpath -m "$1")
mkdir -p "$work/bin" "$work/prof"
common=(-G Ninja -DCMAKE_BUILD_TYPE=Release -DSANDCELL_BUILD_PYTHON=OFF)
# GCC names each profile after its object's path: the use build must reuse the generate build's folder.
cmake -S . -B "$work/pgo" "${common[@]}" -DCMAKE_EXE_LINKER_FLAGS=-fprofile-generate \
  "-DCMAKE_CXX_FLAGS=-fprofile-generate -fprofile-dir=$work/prof -fprofile-update=prefer-atomic"
cmake --build "$work/pgo" --target dem-bench
# Training: the plain scene on 1 and 2 threads, and the 160,000-sphere one.
b="$work/pgo/apps/dem-bench/dem-bench"
"$b" --steps 800 --threads 1 > /dev/null
"$b" --steps 800 --threads 2 > /dev/null
"$b" --tile 2 --steps 60 --threads 2 > /dev/null
cmake -S . -B "$work/pgo" -DCMAKE_EXE_LINKER_FLAGS= \
  "-DCMAKE_CXX_FLAGS=-fprofile-use -fprofile-dir=$work/prof -fprofile-partial-training -Wno-missing-profile"
cmake --build "$work/pgo" --target dem-bench
cp "$b" "$work/bin/dem-bench-pgo"
cmake -S . -B "$work/lto" "${common[@]}" -DCMAKE_INTERPROCEDURAL_OPTIMIZATION=ON
cmake --build "$work/lto" --target dem-bench
cp "$work/lto/apps/dem-bench/dem-bench" "$work/bin/dem-bench-lto"
