#!/usr/bin/env python3
"""bench/compare_builds.py against fake bench programs: the rounds' rotation, the per-round
ratios and medians it prints, and its exit status when the builds' bits differ or a run fails.

Usage: test_compare_builds.py SOURCE_DIR
"""
import os
import subprocess
import sys
import tempfile

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from fakes import expect, make_executable  # noqa: E402

FAKE = """#!/usr/bin/env python3
# A bench program that prints one RESULT line per call, its CPU-seconds the next of a list, and
# appends its name to the call log.
import os, sys
here = os.path.dirname(os.path.abspath(__file__))
name = os.path.basename(__file__)
counter = os.path.join(here, name + ".calls")
calls = int(open(counter).read()) if os.path.exists(counter) else 0
open(counter, "w").write(str(calls + 1))
open(os.path.join(here, "order.log"), "a").write(name + "\\n")
if {fail}:
    sys.exit(3)
seconds = {seconds}[calls]
assert sys.argv[1:] == ["--cells_steps=10"], sys.argv
if {dem_format}:
    # scene threads particles steps wall pts/s/core pts/cpu-s MiB contacts hash
    print(f"RESULT mill_1m 1 1000 10 {{seconds}} 1 {{1000 * 10 / seconds}} 1 0.3 {state}")
else:
    print(f"RESULT le_media_2000 1 1000 10 {{seconds}} {{seconds}} state {state}", file=sys.stderr)
"""


def make_fake(folder, name, seconds, state="00000000000000aa", fail=False, dem_format=False):
    return make_executable(
        folder, name, FAKE.format(seconds=seconds, state=state, fail=fail, dem_format=dem_format))


def run(script, binaries, extra=()):
    return subprocess.run([sys.executable, script, "--rounds", "3", *extra, *binaries, "--",
                           "--cells_steps=10"], capture_output=True, text=True)


def main():
    script = os.path.join(sys.argv[1], "bench", "compare_builds.py")
    with tempfile.TemporaryDirectory() as folder:
        old = make_fake(folder, "old", [2.0, 2.2, 1.8])
        new = make_fake(folder, "new", [1.0, 2.0, 1.5])
        done = run(script, [old, new], ["--label", "old", "--label", "new"])
        expect(done.returncode == 0, f"exit {done.returncode}: {done.stderr}")
        order = open(os.path.join(folder, "order.log")).read().split()
        expect(order == ["old", "new", "new", "old", "old", "new"], f"rotation: {order}")
        want = [
            "le_media_2000/threads:1",
            "  old: CPU-s median 2 (1.8-2.2), 0.005 M particle-steps per CPU-second, "
            "state 00000000000000aa",
            "  new: CPU-s median 1.5 (1-2), 0.007 M particle-steps per CPU-second, "
            "state 00000000000000aa",
            "  old / new per round: 2.000 1.100 1.200; median 1.200, faster in 3 of 3",
        ]
        expect(done.stdout.splitlines() == want, f"printed:\n{done.stdout}")

    with tempfile.TemporaryDirectory() as folder:
        old = make_fake(folder, "old", [1.0, 1.0, 1.0], dem_format=True)
        new = make_fake(folder, "new", [2.0, 2.0, 2.0], state="00000000000000bb", dem_format=True)
        done = run(script, [old, new], ["--label", "old", "--label", "new"])
        expect(done.returncode == 2, f"states differ: exit {done.returncode}")
        expect("  old / new per round: 0.500 0.500 0.500; median 0.500, faster in 0 of 3"
               in done.stdout.splitlines(), f"bench_dem's lines:\n{done.stdout}")
        expect("the builds' states differ: old ['00000000000000aa']; new ['00000000000000bb']"
               in done.stdout, f"no word of the differing states:\n{done.stdout}")

    with tempfile.TemporaryDirectory() as folder:
        old = make_fake(folder, "old", [1.0, 1.0, 1.0])
        new = make_fake(folder, "new", [2.0, 2.0, 2.0], state="00000000000000bb")
        done = run(script, [old, new], ["--other-bits"])
        expect(done.returncode == 0, f"--other-bits: exit {done.returncode}")

    with tempfile.TemporaryDirectory() as folder:
        old = make_fake(folder, "old", [1.0, 1.0, 1.0])
        broken = make_fake(folder, "broken", [1.0, 1.0, 1.0], fail=True)
        done = run(script, [old, broken])
        expect(done.returncode == 1 and "exited with 3" in done.stderr,
               f"a failing run: exit {done.returncode}, {done.stderr}")
    print("compare_builds.py: rotation, ratios, medians, exit statuses as expected")


if __name__ == "__main__":
    main()
