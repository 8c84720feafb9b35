# Test cuda_kernel_check_coverage: every HEXCUT_HD function of src/element/*.hpp,
# src/multigrid/kernels.hpp and src/assembly/fine_cell_kernels.hpp is called in
# cuda/kernel_check.cu (as el::NAME(, mg::NAME( or as::NAME(),
# so that a new kernel body cannot escape the device-code check.
#
#   cmake -DSOURCE_DIR=<repository root> -P check_coverage.cmake

file(GLOB headers ${SOURCE_DIR}/src/element/*.hpp)
list(APPEND headers ${SOURCE_DIR}/src/multigrid/kernels.hpp
  ${SOURCE_DIR}/src/assembly/fine_cell_kernels.hpp)
file(READ ${SOURCE_DIR}/cuda/kernel_check.cu check)
# Pieces of one body, compiled for the device through its wrapper (template arguments
# that the wrapper's call instantiates): multigrid::detail::packed_column(s), the columns of
# packed_apply_add.
set(internal packed_column packed_columns)
set(count 0)
set(missing "")
foreach(header IN LISTS headers)
  file(READ ${header} text)
  # "HEXCUT_HD inline <return type> <name>(" (or HEXCUT_INLINE, the forced inline): the
  # name is the last word before "(".
  string(REGEX MATCHALL "HEXCUT_HD (inline|HEXCUT_INLINE) [A-Za-z0-9_:<> ]+ [A-Za-z0-9_]+\\(" declarations "${text}")
  foreach(declaration IN LISTS declarations)
    string(REGEX MATCH "([A-Za-z0-9_]+)\\($" name "${declaration}")
    set(name "${CMAKE_MATCH_1}")
    list(FIND internal "${name}" internal_index)
    if(NOT internal_index EQUAL -1)
      continue()
    endif()
    math(EXPR count "${count} + 1")
    if(NOT check MATCHES "(el|mg|as)::${name}\\(")
      file(RELATIVE_PATH rel ${SOURCE_DIR} ${header})
      string(APPEND missing "  ${name} (${rel})\n")
    endif()
  endforeach()
endforeach()
if(count LESS 30)
  message(FATAL_ERROR "found only ${count} HEXCUT_HD functions: has their declaration changed?")
endif()
if(missing)
  message(FATAL_ERROR "HEXCUT_HD functions without a wrapper in cuda/kernel_check.cu:\n${missing}")
endif()
message("all ${count} HEXCUT_HD functions have a wrapper in cuda/kernel_check.cu")
