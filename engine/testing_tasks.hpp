#pragma once
// Test task kinds and the "millflow-test" campaign format: the engine runs and is tested without
// any DEM. A test campaign file:
//   {"format": "millflow-test", "name": "demo",
//    "tasks": [{"id": "a", "kind": "sum", "params": {"value": 1}},
//              {"id": "b", "kind": "sum", "params": {"value": 2}, "after": ["a"]}]}
// ("after" names earlier tasks: the upstream tasks, in input order). Kinds:
//   sleep  {"ms": N}                  sleeps N ms in 2 ms steps, polling its stop token
//   fail   {"failures": N}            throws on its first N attempts ever (counted in the store);
//          with {"non_finite": true} it returns a NaN result on them instead of throwing
//   steps  {"steps": N, "step_ms": M} N steps of M ms, each advancing a 64-bit state; checkpoints
//          (step, state) in its work directory after every step, stops at a stop request and
//          continues from the checkpoint when run again (logging "continuing from step k of N";
//          a checkpoint it cannot read is logged as a warning and it starts again from step 0);
//          result {"steps": N, "state": "<16 hex digits>"}
//   sum    {"value": N, "sleep_ms": M, "artifact": true, "skipped": "reason"}
//          result {"sum": N + the "sum" of each input}, plus {"skipped": reason} when given (a
//          task that skipped its work); with "artifact" it also writes sum.txt
//          (and checks its inputs' sum.txt); with MILLFLOW_TEST_TRACE set it appends its key to
//          that file when it starts (crash tests count runs with it)
//   fanout {"children": K, "value": N} result {"sum": N}, declares K sum tasks {"value": i}
#include "engine/campaign.hpp"

namespace millflow::engine {

void add_testing_kinds(KindRegistry& kinds);
// The test kinds plus the "millflow-test" format.
void add_testing(Registry& registry);

// Most sleep tasks ever running at once in this process (reset by the call).
int take_max_concurrent_sleeps();

}  // namespace millflow::engine
