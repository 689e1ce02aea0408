# SPDX-License-Identifier: MIT
# ctest install_find_package (cmake -P): installs the build into a scratch prefix,
# builds tests/install against it with find_package(wvol) and runs the program, then
# compiles the same main.c with `pkg-config --cflags --libs --static wvol` and runs it.
# -D arguments: WVOL_BUILD_DIR, WVOL_WORK_DIR, WVOL_CONFIG (may be empty),
# CMAKE_C_COMPILER, CMAKE_CXX_COMPILER, WVOL_VTK (the build has the VTK adapter).
foreach(var WVOL_BUILD_DIR WVOL_WORK_DIR CMAKE_C_COMPILER)
  if(NOT DEFINED ${var})
    message(FATAL_ERROR "run.cmake: -D${var}=... is required")
  endif()
endforeach()
set(prefix ${WVOL_WORK_DIR}/prefix)
set(consumer ${WVOL_WORK_DIR}/consumer)
file(REMOVE_RECURSE ${WVOL_WORK_DIR})

function(step what)
  execute_process(COMMAND ${ARGN} RESULT_VARIABLE rc OUTPUT_VARIABLE out ERROR_VARIABLE out)
  if(NOT rc EQUAL 0)
    message(FATAL_ERROR "install test: ${what} failed (${rc}):\n${ARGN}\n${out}")
  endif()
  message(STATUS "install test: ${what}: ok")
  set(step_output "${out}" PARENT_SCOPE)
endfunction()

if(NOT WVOL_CONFIG)
  set(WVOL_CONFIG Release)
endif()
step("cmake --install" ${CMAKE_COMMAND} --install ${WVOL_BUILD_DIR} --prefix ${prefix} --config ${WVOL_CONFIG})
if(EXISTS ${prefix}/bin/wvol)
  step("wvol --version" ${prefix}/bin/wvol --version)
  if(NOT step_output MATCHES "^wvol [0-9]+\\.[0-9]+\\.[0-9]+\n$")
    message(FATAL_ERROR "install test: wvol --version printed '${step_output}'")
  endif()
  # the installed program loads the VTK adapter module from the installed library folder
  if(WVOL_VTK)
    step("wvol synth -o .vti" ${prefix}/bin/wvol synth gaussian --size 8 -o ${WVOL_WORK_DIR}/g.vti)
    step("wvol info .vti" ${prefix}/bin/wvol info ${WVOL_WORK_DIR}/g.vti)
  endif()
endif()
set(compilers -DCMAKE_C_COMPILER=${CMAKE_C_COMPILER})
if(CMAKE_CXX_COMPILER)
  list(APPEND compilers -DCMAKE_CXX_COMPILER=${CMAKE_CXX_COMPILER})
endif()
step("configure with find_package(wvol)" ${CMAKE_COMMAND} -S ${CMAKE_CURRENT_LIST_DIR} -B ${consumer}
     -DCMAKE_BUILD_TYPE=Release -DCMAKE_PREFIX_PATH=${prefix} ${compilers})
step("build" ${CMAKE_COMMAND} --build ${consumer})
step("run" ${consumer}/wvol_consumer)
message(STATUS "${step_output}")

# pkg-config, static: the .pc file's Libs.private must be enough to link
find_program(PKG_CONFIG_EXECUTABLE pkg-config)
if(NOT PKG_CONFIG_EXECUTABLE)
  message(STATUS "install test: no pkg-config, its check skipped")
  return()
endif()
file(GLOB_RECURSE pc_files ${prefix}/wvol.pc)
list(LENGTH pc_files npc)
if(NOT npc EQUAL 1)
  message(FATAL_ERROR "install test: expected one wvol.pc under ${prefix}, found: ${pc_files}")
endif()
get_filename_component(pc_dir ${pc_files} DIRECTORY)
set(ENV{PKG_CONFIG_PATH} ${pc_dir})
step("pkg-config" ${PKG_CONFIG_EXECUTABLE} --cflags --libs --static wvol)
string(STRIP "${step_output}" flags)
separate_arguments(flags UNIX_COMMAND "${flags}")
step("compile with pkg-config" ${CMAKE_C_COMPILER} -std=c11 ${CMAKE_CURRENT_LIST_DIR}/main.c
     -o ${WVOL_WORK_DIR}/wvol_consumer_pc ${flags} -lm)
step("pkg-config libdir" ${PKG_CONFIG_EXECUTABLE} --variable=libdir wvol)
string(STRIP "${step_output}" libdir)
set(ENV{LD_LIBRARY_PATH} "${libdir}:$ENV{LD_LIBRARY_PATH}") # a shared libwvol, without an rpath
step("run (pkg-config build)" ${WVOL_WORK_DIR}/wvol_consumer_pc)
message(STATUS "${step_output}")
