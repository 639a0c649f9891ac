// Registration of the micro-benchmarks (bench_train.cpp) with Google Benchmark.
#pragma once

namespace csympnet::bench {

void register_benchmarks();

}  // namespace csympnet::bench
