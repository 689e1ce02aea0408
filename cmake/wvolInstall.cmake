# SPDX-License-Identifier: MIT
# Install rules, included from the root CMakeLists.txt: the public headers, the
# library (static, or shared with WVOL_BUILD_SHARED), the wvol program, the CMake
# package (find_package(wvol) -> wvol::wvol) and the pkg-config file wvol.pc.
include(CMakePackageConfigHelpers)

set(WVOL_CMAKE_INSTALL_DIR ${CMAKE_INSTALL_LIBDIR}/cmake/wvol)
set(WVOL_PC_INSTALL_DIR ${CMAKE_INSTALL_LIBDIR}/pkgconfig)
if(WVOL_BUILD_SHARED)
  set(WVOL_INSTALLED_LIB wvol_shared)
  set(WVOL_PACKAGE_STATIC OFF)
else()
  set(WVOL_INSTALLED_LIB wvol)
  set(WVOL_PACKAGE_STATIC ON)
endif()

install(TARGETS ${WVOL_INSTALLED_LIB} EXPORT wvolTargets
        ARCHIVE DESTINATION ${CMAKE_INSTALL_LIBDIR}
        LIBRARY DESTINATION ${CMAKE_INSTALL_LIBDIR}
        RUNTIME DESTINATION ${CMAKE_INSTALL_BINDIR})
# the C++ adapters' module, which the library loads from the library folder (io/adapters_module.c)
if(TARGET wvol_adapters)
  install(TARGETS wvol_adapters LIBRARY DESTINATION ${CMAKE_INSTALL_LIBDIR})
endif()
if(TARGET wvol_app)
  install(TARGETS wvol_app RUNTIME DESTINATION ${CMAKE_INSTALL_BINDIR})
endif()
# One header per module plus the umbrella wvol.h; the synthetic volumes' header goes
# beside them. Internal headers (libwvol/src) are not installed.
file(GLOB WVOL_PUBLIC_HEADERS CONFIGURE_DEPENDS ${PROJECT_SOURCE_DIR}/libwvol/include/wvol/*.h)
install(FILES ${WVOL_PUBLIC_HEADERS} DESTINATION ${CMAKE_INSTALL_INCLUDEDIR}/wvol)
install(FILES ${PROJECT_SOURCE_DIR}/datasets-synth/wvol_synth.h DESTINATION ${CMAKE_INSTALL_INCLUDEDIR})

# ---- CMake package ----
# A static libwvol carries its dependencies' link lines ($<LINK_ONLY:...>), so the
# package finds them again; the config file records what this build included.
set(WVOL_PACKAGE_FEATURES "")
foreach(dep PNG OPENEXR LAPACKE VTK OPENVDB TINYOBJLOADER)
  if(WVOL_HAVE_${dep})
    list(APPEND WVOL_PACKAGE_FEATURES ${dep})
  endif()
endforeach()
install(EXPORT wvolTargets NAMESPACE wvol:: DESTINATION ${WVOL_CMAKE_INSTALL_DIR})
configure_package_config_file(${PROJECT_SOURCE_DIR}/cmake/wvolConfig.cmake.in
                              ${PROJECT_BINARY_DIR}/wvolConfig.cmake
                              INSTALL_DESTINATION ${WVOL_CMAKE_INSTALL_DIR})
# 0.x: a new minor version may change the API
write_basic_package_version_file(${PROJECT_BINARY_DIR}/wvolConfigVersion.cmake
                                 COMPATIBILITY SameMinorVersion)
install(FILES ${PROJECT_BINARY_DIR}/wvolConfig.cmake ${PROJECT_BINARY_DIR}/wvolConfigVersion.cmake
        DESTINATION ${WVOL_CMAKE_INSTALL_DIR})

# ---- pkg-config ----
# Libs.private (for `pkg-config --static`): the files of the libraries the layers
# link, found by walking the imported targets and what their interfaces link.
function(wvol_link_files out_var)
  set(todo ${ARGN})
  set(seen "")
  set(result "")
  string(TOUPPER "${CMAKE_BUILD_TYPE}" config)
  while(todo)
    list(POP_FRONT todo item)
    if(item MATCHES "^\\$<LINK_ONLY:(.+)>$")
      set(item "${CMAKE_MATCH_1}")
    endif()
    if(item MATCHES "\\$<" OR item IN_LIST seen)
      continue() # configuration-dependent generator expressions are left out
    endif()
    list(APPEND seen "${item}")
    if(TARGET "${item}")
      get_target_property(real "${item}" ALIASED_TARGET)
      if(real)
        list(PREPEND todo ${real})
        continue()
      endif()
      get_target_property(type "${item}" TYPE)
      if(NOT type STREQUAL "INTERFACE_LIBRARY")
        get_target_property(configs "${item}" IMPORTED_CONFIGURATIONS)
        set(loc "")
        foreach(c ${config} ${configs} NOCONFIG)
          if(NOT loc)
            get_target_property(loc "${item}" IMPORTED_LOCATION_${c})
          endif()
        endforeach()
        if(NOT loc)
          get_target_property(loc "${item}" IMPORTED_LOCATION)
        endif()
        if(loc)
          list(APPEND result "${loc}")
        endif()
      endif()
      get_target_property(deps "${item}" INTERFACE_LINK_LIBRARIES)
      if(deps)
        list(APPEND todo ${deps})
      endif()
    elseif(item MATCHES "^-" OR IS_ABSOLUTE "${item}")
      list(APPEND result "${item}")
    else()
      list(APPEND result "-l${item}")
    endif()
  endwhile()
  list(REMOVE_DUPLICATES result)
  set(${out_var} ${result} PARENT_SCOPE)
endfunction()
wvol_link_files(WVOL_PC_LIBS ${WVOL_CORE_DEPS} ${WVOL_IO_DEPS})
if(WVOL_LINKER_LANGUAGE STREQUAL "CXX")
  list(APPEND WVOL_PC_LIBS -lstdc++)
endif()
list(JOIN WVOL_PC_LIBS " " WVOL_PC_LIBS_PRIVATE)
# relocatable: the prefix is found from the .pc file's own folder
file(RELATIVE_PATH WVOL_PC_TO_PREFIX /prefix/${WVOL_PC_INSTALL_DIR} /prefix)
string(REGEX REPLACE "/$" "" WVOL_PC_TO_PREFIX "${WVOL_PC_TO_PREFIX}")
set(WVOL_PC_LIBDIR ${CMAKE_INSTALL_LIBDIR})
set(WVOL_PC_INCLUDEDIR ${CMAKE_INSTALL_INCLUDEDIR})
configure_file(${PROJECT_SOURCE_DIR}/cmake/wvol.pc.in ${PROJECT_BINARY_DIR}/wvol.pc @ONLY)
install(FILES ${PROJECT_BINARY_DIR}/wvol.pc DESTINATION ${WVOL_PC_INSTALL_DIR})
