# ctest python.install: installs the build into PREFIX and imports csympnet from PACKAGE_DIR
# alone, with a fit and a prediction, from a directory that holds no csympnet sources.
file(REMOVE_RECURSE ${PREFIX})
execute_process(COMMAND ${CMAKE_COMMAND} --install ${BUILD_DIR} --prefix ${PREFIX}
                RESULT_VARIABLE rc OUTPUT_QUIET)
if(NOT rc EQUAL 0)
  message(FATAL_ERROR "cmake --install failed (${rc})")
endif()
set(check [=[
import csympnet, os, sys
assert os.path.realpath(csympnet.__file__).startswith(os.path.realpath(sys.argv[1])), csympnet.__file__
from csympnet import plot
m = csympnet.fit(*csympnet.generate("s1", "train"), epochs=20)
assert m.predict([0.5, -0.2], 0.1).shape == (2,)
# python -m csympnet finds the installed command line, <prefix>/bin/csympnet, with nothing
# else to go on (no CSYMPNET_CLI, no csympnet on PATH).
from csympnet import _cli
env = {"PATH": "/usr/bin:/bin"}
assert _cli.find_cli(env) == os.path.join(os.getcwd(), "bin", "csympnet"), _cli.find_cli(env)
import subprocess
out = subprocess.run([sys.executable, "-m", "csympnet", "--version"], env={**env,
                     "PYTHONPATH": sys.argv[1]}, capture_output=True, text=True, check=True)
assert csympnet.__version__ in out.stdout, out
print("installed csympnet", csympnet.__version__, "at", os.path.dirname(csympnet.__file__))
]=])
execute_process(COMMAND ${CMAKE_COMMAND} -E env PYTHONPATH=${PACKAGE_DIR} PYTHONDONTWRITEBYTECODE=1
                        ${PYTHON} -c "${check}" ${PACKAGE_DIR}
                WORKING_DIRECTORY ${PREFIX} RESULT_VARIABLE rc)
if(NOT rc EQUAL 0)
  message(FATAL_ERROR "importing the installed csympnet failed (${rc})")
endif()
