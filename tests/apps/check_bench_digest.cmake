# apps.bench_digest: dem-bench on the shipped dense-20k scene (scene B: the deforming box, so the
# list is rebuilt and contacts open and close) gives the same state digest with 1 and 2 TBB threads
# and with the serial backend, with the dynamic and fixed partitions of chunks to threads, the owner one
# (with its halo) on 2 and 3 threads, the adaptive one (the default, which switches between
# owner and dynamic in its first trial, within the 40 steps), and a different one
# after one more step (the digest sees the state);
# --scaling reports its two worlds equal.
# dem-bench ARGN on scene B: its JSON report (fatal if it exits non-zero).
function(bench_json out)
  execute_process(COMMAND "${BENCH}" ${ARGN} --deform 0.9391 --json
                  RESULT_VARIABLE code OUTPUT_VARIABLE json ERROR_VARIABLE err)
  if(NOT code EQUAL 0)
    message(FATAL_ERROR "dem-bench ${ARGN} exited ${code}: ${json} ${err}")
  endif()
  set(${out} "${json}" PARENT_SCOPE)
endfunction()
function(bench_digest out)
  bench_json(json ${ARGN})
  string(JSON digest GET "${json}" digest)
  set(${out} "${digest}" PARENT_SCOPE)
endfunction()
bench_digest(one --steps 40 --threads 1)
bench_digest(serial --steps 40 --serial)
bench_digest(later --steps 41 --threads 2)
bench_digest(fixed --steps 40 --threads 2 --partition fixed)
bench_digest(dynamic --steps 40 --threads 2 --partition dynamic)
bench_digest(owner2 --steps 40 --threads 2 --partition owner)
bench_digest(owner3 --steps 40 --threads 3 --partition owner)
bench_json(two_json --steps 40 --threads 2)
string(JSON two GET "${two_json}" digest)
string(JSON two_dynamic GET "${two_json}" partition_steps dynamic)
string(JSON two_wall GET "${two_json}" wall_s)
# Its first batch (owner) ends after 16 steps and 20 ms of timed steps: where 40 steps took 40 ms
# or more (1 ms a step; 1.5-4 ms on the 2-core host), it ends by step 21, and steps run as dynamic.
if(two_wall GREATER_EQUAL 0.04 AND two_dynamic EQUAL 0)
  message(FATAL_ERROR "the default (adaptive) partition ran no step as dynamic in 40 steps of ${two_wall} s: ${two_json}")
endif()
message(STATUS "digests: 1 thread ${one}, 2 threads ${two}, serial ${serial}, one step later ${later}")
if(NOT one STREQUAL two OR NOT one STREQUAL serial OR NOT one STREQUAL fixed OR NOT one STREQUAL dynamic
   OR NOT one STREQUAL owner2 OR NOT one STREQUAL owner3)
  message(FATAL_ERROR "state digest depends on the thread count or the partition: ${one} / ${two} (adaptive) / ${serial} / fixed ${fixed} / dynamic ${dynamic} / owner ${owner2}, 3 threads ${owner3}")
endif()
# The hooke law (systems/laws/hooke.hpp) through the same pass: bitwise the same for 1 and 2
# threads, and not Hertz's state.
bench_digest(hooke_one --steps 40 --threads 1 --normal hooke --vchar 0.5)
bench_digest(hooke_two --steps 40 --threads 2 --normal hooke --vchar 0.5)
if(NOT hooke_one STREQUAL hooke_two OR hooke_one STREQUAL one)
  message(FATAL_ERROR "hooke: digests ${hooke_one} (1 thread) / ${hooke_two} (2 threads), hertz ${one}")
endif()
if(one STREQUAL later)
  message(FATAL_ERROR "state digest unchanged by one more step: it does not see the state")
endif()

# --scaling steps a 1-thread and a 2-thread world of scene B alternately (2 blocks of 20 steps),
# and two more 1-thread worlds at once from two threads of their own: it must report all four
# final states bitwise equal, and exit 0.
bench_json(json --scaling --steps 20 --rounds 2 --threads 2)
string(JSON equal GET "${json}" digests_equal)
string(JSON rounds LENGTH "${json}" ratios)
if(NOT equal OR NOT rounds EQUAL 2)
  message(FATAL_ERROR "dem-bench --scaling: digests_equal = ${equal}, ${rounds} ratios (expected true, 2): ${json}")
endif()
# The two references of the same rounds (independent worlds, streaming pass) and the distribution of
# the rounds (p10, p90): measured rates and their ratios, so positive and finite on any machine
# (their values are the machine's; not asserted).
foreach(key jobs_median_ratio stream_median_ratio p10_one p90_one p10_many p90_many p10_ratio p90_ratio
            p10_many_over_median_one)
  string(JSON value GET "${json}" ${key})
  if(NOT value GREATER 0 OR value MATCHES "nan|inf")
    message(FATAL_ERROR "dem-bench --scaling: ${key} = ${value} (expected a positive number): ${json}")
  endif()
endforeach()
# Order statistics of the same rounds: p10 <= median <= p90.
string(JSON p10 GET "${json}" p10_ratio)
string(JSON mid GET "${json}" median_ratio)
string(JSON p90 GET "${json}" p90_ratio)
if(p10 GREATER mid OR mid GREATER p90)
  message(FATAL_ERROR "dem-bench --scaling: p10_ratio ${p10} <= median_ratio ${mid} <= p90_ratio ${p90} fails: ${json}")
endif()
# The per-system seconds of both worlds over the same rounds: every system of the step has a pair,
# and the contact pass, which ran in every step of both, took time in both.
string(JSON systems LENGTH "${json}" systems)
foreach(world 0 1)
  string(JSON seconds GET "${json}" systems contact ${world})
  if(systems LESS 4 OR NOT seconds GREATER 0)
    message(FATAL_ERROR "dem-bench --scaling: ${systems} systems, contact[${world}] = ${seconds} s: ${json}")
  endif()
endforeach()
