# ctest install.cmake_package: `cmake --install` the build into a scratch PREFIX, then
# configure, build and run examples/cmake_consumer against it with find_package(csympnet)
# (CMAKE_PREFIX_PATH=PREFIX alone), and run the installed CLI.
#   -DBUILD_DIR= -DSOURCE_DIR= -DWORK= -DCXX= -DLIBDIR= [-DCXX_FLAGS= -DLINK_FLAGS=]
foreach(var BUILD_DIR SOURCE_DIR WORK CXX LIBDIR)
  if(NOT DEFINED ${var})
    message(FATAL_ERROR "cmake_package_check: -D${var}= is required")
  endif()
endforeach()
set(prefix ${WORK}/prefix)
set(consumer ${WORK}/consumer-build)
file(REMOVE_RECURSE ${WORK})

function(run what)
  execute_process(COMMAND ${ARGN} RESULT_VARIABLE rc OUTPUT_VARIABLE out ERROR_VARIABLE err)
  if(NOT rc EQUAL 0)
    message(FATAL_ERROR "${what} failed (${rc}):\n${out}\n${err}")
  endif()
  set(out "${out}" PARENT_SCOPE)
endfunction()

run("cmake --install" ${CMAKE_COMMAND} --install ${BUILD_DIR} --prefix ${prefix})
foreach(f include/csympnet/models/model.hpp include/csympnet/core/types.hpp
          ${LIBDIR}/libcsympnet.a
          ${LIBDIR}/cmake/csympnet/csympnetConfig.cmake
          ${LIBDIR}/cmake/csympnet/csympnetConfigVersion.cmake
          ${LIBDIR}/cmake/csympnet/csympnetTargets.cmake bin/csympnet)
  if(NOT EXISTS ${prefix}/${f})
    message(FATAL_ERROR "not installed: ${prefix}/${f}")
  endif()
endforeach()
run("installed csympnet --version" ${prefix}/bin/csympnet --version)
if(NOT out MATCHES "^csympnet [0-9]+\\.[0-9]+\\.[0-9]+")
  message(FATAL_ERROR "installed csympnet --version printed:\n${out}")
endif()

# The consumer sees only PREFIX: a csympnet installed elsewhere (/usr/local) must not be used.
run("configuring the consumer" ${CMAKE_COMMAND} -S ${SOURCE_DIR}/examples/cmake_consumer
    -B ${consumer} -DCMAKE_BUILD_TYPE=Release -DCMAKE_CXX_COMPILER=${CXX}
    "-DCMAKE_CXX_FLAGS=${CXX_FLAGS}" "-DCMAKE_EXE_LINKER_FLAGS=${LINK_FLAGS}"
    -DCMAKE_PREFIX_PATH=${prefix} -DCMAKE_FIND_USE_PACKAGE_REGISTRY=OFF)
file(STRINGS ${consumer}/CMakeCache.txt found REGEX "^csympnet_DIR:")
file(REAL_PATH ${prefix} real_prefix)
string(REGEX REPLACE "^csympnet_DIR:[A-Z]+=" "" found "${found}")
file(REAL_PATH "${found}" found)
string(FIND "${found}/" "${real_prefix}/" at)
if(NOT at EQUAL 0)
  message(FATAL_ERROR "the consumer found csympnet at '${found}', not under ${real_prefix}")
endif()
run("building the consumer" ${CMAKE_COMMAND} --build ${consumer})
run("running the consumer" ${consumer}/fit_s1 300)
message("${out}")
if(NOT out MATCHES "gamma_hat = [0-9]")
  message(FATAL_ERROR "the consumer did not print gamma_hat")
endif()
