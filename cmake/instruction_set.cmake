# The x86-64 instruction set the DEM library is compiled for (MILLFLOW_ISA), and the
# floating-point flags that make every choice give the same bits.
#
# The dense cells' contact law is SSE2 code in two-operand form by default; compiled for AVX2
# (x86-64-v3) the same arithmetic takes about 14% fewer instructions (docs/benchmarks.md,
# "The instruction set"). Results must not depend on the choice, so:
#   -ffp-contract=off  GCC fuses a * b + c into one FMA (one rounding instead of two) wherever the
#                      target has FMA, even under -std=c++20; off, every level rounds alike;
#   -fno-math-errno    sqrt becomes the one instruction it is, without the test that would set
#                      errno for a negative argument (nothing here reads errno after a math call);
#   only dem/          the DEM library uses fixed-size 3-vectors and 3 x 3 matrices, which Eigen
#                      does not vectorize itself; the compiler's vector instructions do the same
#                      IEEE operations as the scalar ones and reassociate nothing (no -ffast-math).
#                      Eigen's own packet kernels (the eigen-solver in method/) sum in an order
#                      that depends on the packet width, so the other libraries keep the default.
# The golden tests (relative tolerance 1e-9, generated on an x86-64 build) hold at every level: a
# difference in bits would grow far past that in a DEM run.
#
# MILLFLOW_ISA:
#   native-level  (default) the highest of x86-64-v2 and x86-64-v3 that the build host runs, found
#                 by running a probe at configure time; the binary then needs a machine of that
#                 level (on a mixed cluster, build on the oldest node or name a level)
#   x86-64, x86-64-v2, x86-64-v3, x86-64-v4   that level (-march=LEVEL)
#   none          no -march flag: the compiler's default
# The default stops at v3: AVX-512 (v4) was not faster on the cells (docs/benchmarks.md).
set(MILLFLOW_ISA "native-level" CACHE STRING
    "x86-64 instruction set of the DEM library: native-level, x86-64, x86-64-v2, x86-64-v3, x86-64-v4 or none")
set_property(CACHE MILLFLOW_ISA PROPERTY STRINGS native-level x86-64 x86-64-v2 x86-64-v3 x86-64-v4 none)

function(millflow_probe_isa_level out)
  set(${out} "none" PARENT_SCOPE)
  if(CMAKE_CROSSCOMPILING OR NOT CMAKE_SYSTEM_PROCESSOR MATCHES "^(x86_64|AMD64|amd64)$")
    return()
  endif()
  set(probe_source "${CMAKE_BINARY_DIR}/CMakeFiles/millflow_isa_probe.cpp")
  file(WRITE "${probe_source}" [=[
#include <cstdio>
int main() {
  std::puts(__builtin_cpu_supports("x86-64-v3")   ? "x86-64-v3"
            : __builtin_cpu_supports("x86-64-v2") ? "x86-64-v2"
                                                  : "x86-64");
}
]=])
  try_run(probe_ran probe_compiled "${CMAKE_BINARY_DIR}/CMakeFiles/millflow_isa_probe"
          "${probe_source}" RUN_OUTPUT_VARIABLE probe_output)
  if(probe_compiled AND probe_ran EQUAL 0)
    string(STRIP "${probe_output}" probe_output)
    set(${out} "${probe_output}" PARENT_SCOPE)
  endif()
endfunction()

if(MILLFLOW_ISA STREQUAL "native-level")
  millflow_probe_isa_level(MILLFLOW_ISA_CHOSEN)
elseif(MILLFLOW_ISA MATCHES "^(x86-64|x86-64-v2|x86-64-v3|x86-64-v4|none)$")
  set(MILLFLOW_ISA_CHOSEN "${MILLFLOW_ISA}")
else()
  message(FATAL_ERROR "MILLFLOW_ISA=${MILLFLOW_ISA} is not an instruction set this build knows; "
                      "use native-level, x86-64, x86-64-v2, x86-64-v3, x86-64-v4 or none")
endif()
message(STATUS "millflow: the DEM library for instruction set ${MILLFLOW_ISA_CHOSEN} (MILLFLOW_ISA=${MILLFLOW_ISA})")

# millflow_use_isa(TARGET): the chosen level and the bit-keeping flags on TARGET's own sources.
function(millflow_use_isa target)
  if(NOT MILLFLOW_ISA_CHOSEN STREQUAL "none")
    target_compile_options(${target} PRIVATE -march=${MILLFLOW_ISA_CHOSEN})
  endif()
  target_compile_options(${target} PRIVATE -ffp-contract=off -fno-math-errno)
endfunction()
