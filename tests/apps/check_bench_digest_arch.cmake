# apps.bench_digest_arch: dem-bench on the library as configured (SANDCELL_ARCH, e.g. x86-64-v3)
# and dem-bench-portable on the same sources built for the baseline instruction set give the same
# state digest (bitwise equal positions, velocities, spins, contact histories and cell) for every
# contact-model variant, on scene B (the deforming box: affine terms in the integrator and the
# contact velocities): the list build with its spatial sort, then 60 steps of the contact pass,
# the gather and the integrator, the loops the compiler vectorizes at different widths in the two
# builds. What makes them agree: no fused multiply-add in either, no reassociation (no
# -ffast-math), and IEEE sqrt and division, correctly rounded at any width.
function(arch_digest out bench)
  execute_process(COMMAND "${bench}" ${ARGN} --steps 60 --threads 2 --deform 0.9391 --json
                  RESULT_VARIABLE code OUTPUT_VARIABLE json ERROR_VARIABLE err)
  if(NOT code EQUAL 0)
    message(FATAL_ERROR "${bench} ${ARGN} exited ${code}: ${err}")
  endif()
  string(JSON digest GET "${json}" digest)
  string(JSON arch GET "${json}" arch)
  set(${out} "${digest}" PARENT_SCOPE)
  set(${out}_arch "${arch}" PARENT_SCOPE)
endfunction()
foreach(label "--rolling epsd2" "--rolling none" "--rolling epsd" "--rolling cdt" "--tangential incremental"
              "--compat")
  separate_arguments(args UNIX_COMMAND "${label}")
  arch_digest(built "${BENCH}" ${args})
  arch_digest(portable "${PORTABLE}" ${args})
  message(STATUS "${label}: ${built_arch} ${built}, ${portable_arch} ${portable}")
  if(built_arch STREQUAL portable_arch)
    message(FATAL_ERROR "both programs report the instruction set ${built_arch}: not two builds to compare")
  endif()
  if(NOT built STREQUAL portable)
    message(FATAL_ERROR "${label}: the ${built_arch} build gives digest ${built}, the portable build ${portable}")
  endif()
endforeach()
