#!/usr/bin/env python3
"""bench/count_instructions.py against a fake valgrind and a fake callgrind_annotate: the counts
per particle-step it prints for the step and its passes, the ratios between builds, and its exit
status when the builds' bits differ or a run fails.

Usage: test_count_instructions.py SOURCE_DIR
"""
import os
import subprocess
import sys
import tempfile

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from fakes import expect, make_executable  # noqa: E402

# The fake valgrind runs nothing: it prints the RESULT line of the build named last before "--"...
# which is the bench program's path; its name picks the state hash and the counts' scale.
FAKE_VALGRIND = """#!/usr/bin/env python3
import os, sys
args = sys.argv[1:]
out = next(a.split("=", 1)[1] for a in args if a.startswith("--callgrind-out-file="))
binary = next(a for a in args if not a.startswith("--"))
name = os.path.basename(binary)
if name == "broken":
    sys.exit(5)
open(out, "w").write(name)
state = "00000000000000bb" if name == "other" else "00000000000000aa"
print(f"RESULT le_media_2000 1 1000 10 0.5 0.5 state {state}", file=sys.stderr)
"""

# Counts for 10,000 particle-steps; the build named "new" executes 10% fewer instructions in the
# pair pass and misses half as often in the gather, "quiet" never misses in the drift; "." is
# callgrind_annotate's zero. The pair pass is listed twice (an inlined part under another file):
# the larger line counts.
FAKE_ANNOTATE = """#!/usr/bin/env python3
import sys
name = open(sys.argv[-1]).read()
pair = 5000000 if name != "new" else 4500000
gather_misses = 20000 if name != "new" else 10000
print("Ir DLmr DLmw")
print("10,000,000 (100.0%) 100,000 (100.0%) 50,000 (100.0%)  PROGRAM TOTALS")
print("10,000,000 (100.0%) 100,000 (100.0%) 50,000 (100.0%)  ???:main [/bin/x]")
print(f"{pair:,} (50.0%) 60,000 (60.0%) 30,000 (60.0%)  "
      "/src/dem/system.cpp:millflow::dem::System::compute_pair_forces(double) [/bin/x]")
print("1,000,000 (10.0%) 6,000 (6.0%) 3,000 (6.0%)  "
      "/usr/include/tbb/task.h:millflow::dem::System::compute_pair_forces(double)")
print("900,000 (9.0%) 5,000 (5.0%) 0 (0.0%)  /src/dem/system.cpp:millflow::dem::System::"
      "compute_pair_forces(double)::{lambda(auto:1 const&)#1}::operator()<int>(int const&) const")
print(f"2,000,000 (20.0%) {gather_misses:,} (20.0%) 10,000 (20.0%)  "
      "/src/dem/system.cpp:millflow::dem::System::compute_particle_forces(double, bool) [/bin/x]")
drift_misses = "10,000 (10.0%) ." if name != "quiet" else ". ."
print(f"500,000 (5.0%) {drift_misses}  "
      "/src/dem/system.cpp:millflow::dem::System::kick_and_drift() [/bin/x]")
"""


def run(script, folder, binaries, extra=()):
    env = dict(os.environ, VALGRIND=os.path.join(folder, "valgrind"),
               CALLGRIND_ANNOTATE=os.path.join(folder, "callgrind_annotate"))
    return subprocess.run([sys.executable, script, *extra,
                           *[os.path.join(folder, b) for b in binaries], "--", "--cells_steps=10"],
                          capture_output=True, text=True, env=env)


def main():
    script = os.path.join(sys.argv[1], "bench", "count_instructions.py")
    with tempfile.TemporaryDirectory() as folder:
        make_executable(folder, "valgrind", FAKE_VALGRIND)
        make_executable(folder, "callgrind_annotate", FAKE_ANNOTATE)
        done = run(script, folder, ["old", "new"], ["--label", "old", "--label", "new"])
        expect(done.returncode == 0, f"exit {done.returncode}: {done.stderr}")
        want = [
            "le_media_2000/threads:1, per particle-step (last level 1048576 bytes): "
            "instructions, misses read + written",
            "  old (state 00000000000000aa): step 1000.0, 10.00 + 5.00; "
            "pair pass 500.0, 6.00 + 3.00; force gather 200.0, 2.00 + 1.00; "
            "drift 50.0, 1.00 + 0.00",
            "  new (state 00000000000000aa): step 1000.0, 10.00 + 5.00; "
            "pair pass 450.0, 6.00 + 3.00; force gather 200.0, 1.00 + 1.00; "
            "drift 50.0, 1.00 + 0.00",
            "  new / old: instructions, misses: step 1.000, 1.000; pair pass 0.900, 1.000; "
            "force gather 1.000, 0.667; drift 1.000, 1.000",
        ]
        expect(done.stdout.splitlines() == want, f"printed:\n{done.stdout}")

        done = run(script, folder, ["quiet", "old"], ["--label", "quiet", "--label", "old"])
        expect(done.stdout.splitlines()[-1].endswith("drift 1.000, -"),
               f"no misses to compare with:\n{done.stdout}")

        done = run(script, folder, ["old", "other"])
        expect(done.returncode == 2 and "the builds' states differ" in done.stdout,
               f"states differ: exit {done.returncode}\n{done.stdout}")
        done = run(script, folder, ["old", "other"], ["--other-bits"])
        expect(done.returncode == 0, f"--other-bits: exit {done.returncode}")
        done = run(script, folder, ["old", "broken"])
        expect(done.returncode == 1 and "exited with 5" in done.stderr,
               f"a failing run: exit {done.returncode}, {done.stderr}")
    print("count_instructions.py: counts per particle-step, ratios, exit statuses as expected")


if __name__ == "__main__":
    main()
