# coupling/ and apps/ see the fluid through fluid/immersed_fluid.hpp only (STYLE.md lesson 13): none of their
# files, nor the coupling layer's fake-fluid test, includes a header of a discretisation behind it (the VMS
# solver's). Run by CTest as FluidInterface.CouplingAndAppsIncludeNoDiscretisation:
#   cmake -DROOT=<source dir> -P tests/check_fluid_interface.cmake
# A second discretisation adds its headers to `private_headers`.
set(private_headers fluid_solver vms_kernel vms_point_state element_basis point_evaluation seq_baij_inserter)
list(JOIN private_headers "|" alternatives)
file(GLOB files ${ROOT}/coupling/*.hpp ${ROOT}/coupling/*.cpp ${ROOT}/apps/*.hpp ${ROOT}/apps/*.cpp
     ${ROOT}/tests/unit/coupling/test_fluid_interface.cpp)
list(LENGTH files n)
if(n LESS 10)
  message(FATAL_ERROR "check_fluid_interface: found only ${n} files under ${ROOT} (wrong -DROOT?)")
endif()
set(offences "")
foreach(f IN LISTS files)
  file(STRINGS ${f} lines REGEX "^[ \t]*#[ \t]*include[ \t]*[\"<]fluid/(${alternatives})\\.hpp[\">]")
  foreach(l IN LISTS lines)
    file(RELATIVE_PATH rel ${ROOT} ${f})
    string(APPEND offences "\n  ${rel}: ${l}")
  endforeach()
endforeach()
if(offences)
  message(FATAL_ERROR "coupling/ and apps/ must hold the fluid as fluid::ImmersedFluid "
                      "(fluid/immersed_fluid.hpp), not include a discretisation's header:${offences}")
endif()
message(STATUS "check_fluid_interface: ${n} files of coupling/ and apps/ include no discretisation header")
