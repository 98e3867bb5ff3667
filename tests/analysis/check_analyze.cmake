# analysis.analyze_command: `triaxial analyze` on the small campaign writes the report, the
# machine-readable summary and every figure (PNG and SVG), and exits 0.
file(REMOVE_RECURSE "${OUT}")
execute_process(COMMAND "${TRIAXIAL}" analyze "${RUN}" --out "${OUT}" --all
                RESULT_VARIABLE code OUTPUT_VARIABLE out ERROR_VARIABLE err)
if(NOT code EQUAL 0)
  message(FATAL_ERROR "triaxial analyze exited ${code}:\n${out}\n${err}")
endif()
foreach(f report.md summary.json csl.png csl.svg pi_plane.png pi_plane.svg dilatancy-constant_p.png
          dilatancy-constant_p.svg)
  if(NOT EXISTS "${OUT}/${f}")
    message(FATAL_ERROR "triaxial analyze did not write ${f}")
  endif()
endforeach()
# One stress-strain figure per (path, p0): three p0 here.
file(GLOB stress_strain "${OUT}/stress_strain-*.png")
list(LENGTH stress_strain n)
if(NOT n EQUAL 3)
  message(FATAL_ERROR "expected 3 stress-strain figures, found ${n}: ${stress_strain}")
endif()
file(READ "${OUT}/report.md" report)
foreach(heading "ritical state line" "M(theta)" "ilatancy")
  string(FIND "${report}" "${heading}" at)
  if(at EQUAL -1)
    message(FATAL_ERROR "report.md lacks a section on '${heading}'")
  endif()
endforeach()
# Bad input: one line, exit 2.
execute_process(COMMAND "${TRIAXIAL}" analyze "${OUT}/report.md" RESULT_VARIABLE code ERROR_VARIABLE err)
if(NOT code EQUAL 2)
  message(FATAL_ERROR "triaxial analyze on a non-HDF5 file exited ${code}, expected 2: ${err}")
endif()
