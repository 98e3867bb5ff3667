# apps.bench_digest: dem-bench on the shipped dense-20k scene (scene B: the deforming box, so the
# list is rebuilt and contacts open and close) gives the same state digest with 1 and 2 TBB threads
# and with the serial backend, and a different one after one more step (the digest sees the state).
function(bench_digest out)
  execute_process(COMMAND "${BENCH}" ${ARGN} --deform 0.9391 --json
                  RESULT_VARIABLE code OUTPUT_VARIABLE json ERROR_VARIABLE err)
  if(NOT code EQUAL 0)
    message(FATAL_ERROR "dem-bench ${ARGN} exited ${code}: ${err}")
  endif()
  string(JSON digest GET "${json}" digest)
  set(${out} "${digest}" PARENT_SCOPE)
endfunction()
bench_digest(one --steps 40 --threads 1)
bench_digest(two --steps 40 --threads 2)
bench_digest(serial --steps 40 --serial)
bench_digest(later --steps 41 --threads 2)
message(STATUS "digests: 1 thread ${one}, 2 threads ${two}, serial ${serial}, one step later ${later}")
if(NOT one STREQUAL two OR NOT one STREQUAL serial)
  message(FATAL_ERROR "state digest depends on the thread count: ${one} / ${two} / ${serial}")
endif()
if(one STREQUAL later)
  message(FATAL_ERROR "state digest unchanged by one more step: it does not see the state")
endif()
