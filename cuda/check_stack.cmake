# Compiler launcher of the kernel check (cuda/CMakeLists.txt): runs the nvcc command given
# after `--`, which has ptxas report every function's resources (-Xptxas=-v), writes that
# report to REPORT, and fails the compilation (removing its object file, so the next build
# tries again) when a function's stack frame exceeds LIMIT bytes per thread.
#
#   cmake -DLIMIT=<bytes> -DREPORT=<file> -P check_stack.cmake -- <nvcc command...>

set(command "")
set(output_file "")
set(take_output OFF)
set(after_dashes OFF)
math(EXPR last "${CMAKE_ARGC} - 1")
foreach(i RANGE 1 ${last})
  set(arg "${CMAKE_ARGV${i}}")
  if(after_dashes)
    list(APPEND command "${arg}")
    if(take_output)
      set(output_file "${arg}")
      set(take_output OFF)
    elseif(arg STREQUAL "-o")
      set(take_output ON)
    endif()
  elseif(arg STREQUAL "--")
    set(after_dashes ON)
  endif()
endforeach()
if(NOT command OR NOT LIMIT OR NOT REPORT)
  message(FATAL_ERROR "usage: cmake -DLIMIT=<bytes> -DREPORT=<file> -P check_stack.cmake -- <nvcc command>")
endif()

execute_process(COMMAND ${command} RESULT_VARIABLE status OUTPUT_VARIABLE out ERROR_VARIABLE out)
file(WRITE "${REPORT}" "${out}")
if(NOT status EQUAL 0)
  message("${out}")
  file(REMOVE "${output_file}")
  message(FATAL_ERROR "kernel check: nvcc failed (${status})")
endif()

# ptxas -v prints, for each function and architecture:
#   ptxas info    : Function properties for <name>
#       <N> bytes stack frame, <S> bytes spill stores, <L> bytes spill loads
# (entry functions first with "Compiling entry function '<name>' for 'sm_XX'").
string(REPLACE "\n" ";" lines "${out}")
# Whatever else nvcc said (warnings) is shown as the compiler would show it.
set(other "")
foreach(line IN LISTS lines)
  if(NOT line MATCHES "^ptxas info|^    [0-9]+ bytes stack frame" AND NOT line STREQUAL "")
    string(APPEND other "${line}\n")
  endif()
endforeach()
if(other)
  message("${other}")
endif()
set(name "")
set(arch "")
set(count 0)
set(largest -1)
set(largest_name "")
set(too_large "")
foreach(line IN LISTS lines)
  if(line MATCHES "Compiling entry function '([^']+)' for '([^']+)'")
    set(arch "${CMAKE_MATCH_2}")
  elseif(line MATCHES "Function properties for ([^ ]+)")
    set(name "${CMAKE_MATCH_1}")
  elseif(line MATCHES "([0-9]+) bytes stack frame, ([0-9]+) bytes spill stores, ([0-9]+) bytes spill loads")
    set(stack "${CMAKE_MATCH_1}")
    math(EXPR count "${count} + 1")
    if(stack GREATER largest)
      set(largest "${stack}")
      set(largest_name "${name} (${arch})")
    endif()
    if(stack GREATER LIMIT)
      string(APPEND too_large "  ${name} (${arch}): ${stack} bytes stack frame\n")
    endif()
  endif()
endforeach()
if(count EQUAL 0)
  file(REMOVE "${output_file}")
  message(FATAL_ERROR "kernel check: no ptxas resource report in the nvcc output (is -Xptxas=-v set?)")
endif()
if(too_large)
  file(REMOVE "${output_file}")
  message(FATAL_ERROR "kernel check: stack frames above the limit of ${LIMIT} bytes per thread "
                      "(doc/theory.md, \"Kernel bodies for a CUDA backend\"):\n${too_large}"
                      "full ptxas report: ${REPORT}")
endif()
message("kernel check: ${count} function reports, largest stack frame ${largest} bytes "
        "(${largest_name}), limit ${LIMIT}; report in ${REPORT}")
