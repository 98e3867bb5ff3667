# apps.bench_digest_arch: dem-bench on the library as configured (SANDCELL_ARCH, e.g. x86-64-v3)
# and dem-bench of the portable tree (the same sources built for the baseline instruction set) give the same
# state digest (bitwise equal positions, velocities, spins, contact histories and cell) for every
# contact-model variant, on scene B (the deforming box: affine terms in the integrator and the
# contact velocities): the list build with its spatial sort, then 60 steps of the contact pass,
# the gather and the integrator, the loops the compiler vectorizes at different widths in the two
# builds. What makes them agree: no fused multiply-add in either, no reassociation (no
# -ffast-math), and IEEE sqrt and division, correctly rounded at any width.
function(arch_digest out bench)
  execute_process(COMMAND "${bench}" --steps 60 --threads 2 ${ARGN} --json
                  RESULT_VARIABLE code OUTPUT_VARIABLE json ERROR_VARIABLE err)
  if(NOT code EQUAL 0)
    message(FATAL_ERROR "${bench} ${ARGN} exited ${code}: ${err}")
  endif()
  string(JSON digest GET "${json}" digest)
  string(JSON servo GET "${json}" servo_stress_digest)
  string(APPEND digest " servo ${servo}")
  string(JSON arch GET "${json}" arch)
  set(${out} "${digest}" PARENT_SCOPE)
  set(${out}_arch "${arch}" PARENT_SCOPE)
endfunction()
# Scene B for the laws; scene A with the servo (which holds the cell) for the stress the contact pass
# sums per block for it, compared by the bits of the servo's last stress.
foreach(label "--deform 0.9391 --rolling epsd2" "--deform 0.9391 --rolling none" "--deform 0.9391 --rolling epsd"
              "--deform 0.9391 --rolling cdt" "--deform 0.9391 --tangential incremental" "--deform 0.9391 --compat"
              "--servo")
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
