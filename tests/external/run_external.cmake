# What a user does with cellfsi: install it, build a project of one's own against the package, run it; and run
# the installed cellfsi's default scene (found in <prefix>/share/cellfsi/scenes). Run by ctest:
#   cmake -DBUILD_DIR=<cellfsi build> -DSOURCE_DIR=<cellfsi source> -DWORK_DIR=<scratch> -P run_external.cmake
function(run)
  execute_process(COMMAND ${ARGN} RESULT_VARIABLE rc OUTPUT_VARIABLE out ERROR_VARIABLE err)
  if(NOT rc EQUAL 0)
    message(FATAL_ERROR "failed (${rc}): ${ARGN}\n${out}\n${err}")
  endif()
  message(STATUS "${out}")
endfunction()
file(REMOVE_RECURSE ${WORK_DIR})
run(${CMAKE_COMMAND} --install ${BUILD_DIR} --prefix ${WORK_DIR}/prefix)
run(${CMAKE_COMMAND} -S ${SOURCE_DIR}/tests/external/rigid_body -B ${WORK_DIR}/build -DCMAKE_BUILD_TYPE=Release
    -DCMAKE_PREFIX_PATH=${WORK_DIR}/prefix)
run(${CMAKE_COMMAND} --build ${WORK_DIR}/build -j 2)
run(${WORK_DIR}/build/rigid_body)
run(${WORK_DIR}/prefix/bin/cellfsi -fluid_elements 48,24 -fluid_degree 2 -solid_membrane_elements 1,0
    -final_time 2e-3 -output_every 0 -output_dir ${WORK_DIR}/default_scene)
file(REMOVE_RECURSE ${WORK_DIR})
