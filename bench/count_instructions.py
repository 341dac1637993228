#!/usr/bin/env python3
"""What one or more builds of a bench program execute per particle-step, whatever the host's speed.

Runs each build once under callgrind (valgrind) with its cache model, counting only inside the
timed steps, and prints per particle-step the instructions and the last-level cache misses (read,
written) of the whole step and of its passes: the pair pass, the force gather (with the closing
kick), the drift (with the opening kick) and the neighbour rebuilds. Instructions are exact and the
cache model deterministic, so two builds compare without the host's jitter (which the CPU-seconds
of bench/compare_builds.py carry); a memory-bound cell's speed follows its misses more than its
instructions (docs/benchmarks.md). Checks that the builds end in the same state hash unless told.

    bench/count_instructions.py [--collect PATTERN] [--ll BYTES] [--label NAME]... BIN... \\
        -- BENCH_ARGS...

e.g. 20 steps of cement_load15, an old build against this one:

    bench/count_instructions.py /tmp/old/bench/bench_cells build/bench/bench_cells -- \\
        --cells_cache=DIR --cells_steps=20 --benchmark_filter='^cement_load15/threads:1/' \\
        --benchmark_min_time=0

--collect is the function whose calls are counted: '*ShearCellRun::advance*' (bench_cells, the
default) or '*System::step*' (bench_dem). --ll is the modelled last-level cache (default 1 MiB,
a core's L2: the host's L3 is shared). VALGRIND and CALLGRIND_ANNOTATE name the two programs.
Exit status 0, 2 when the builds' state hashes differ (without --other-bits), 1 on an error.
"""
import os
import re
import sys
import tempfile

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from compare_builds import (  # noqa: E402
    builds_parser, parse_builds, run_bench, run_checked, run_script)

# The step's passes: a function of each, whose inclusive counts are the pass's.
PASSES = [
    ("pair pass", "System::compute_pair_forces(double)"),
    ("force gather", "System::compute_particle_forces(double, bool)"),
    ("drift", "System::kick_and_drift()"),
    ("rebuilds", "System::update_neighbors(bool)"),
]

# A count and its share ("1,234 (5.6%)"), or "." for none; three of them, then where.
COUNT = r"([\d,]+\s+\([^)]*\)|\.)"
LINE = re.compile(rf"^\s*{COUNT}\s+{COUNT}\s+{COUNT}\s+(.*)$")


def count_of(column):
    return 0 if column == "." else int(column.split()[0].replace(",", ""))


def parse_annotation(text):
    """{name: (instructions, ll_read_misses, ll_write_misses)} for the total and each pass, from
    `callgrind_annotate --inclusive=yes --show=Ir,DLmr,DLmw`. A function listed under several
    files (inlined parts) counts by its largest line, the outermost call."""
    counts = {}
    for line in text.splitlines():
        match = LINE.match(line)
        if not match:
            continue
        numbers = tuple(count_of(match.group(k)) for k in (1, 2, 3))
        where = match.group(4)
        if where.startswith("PROGRAM TOTALS"):
            counts["step"] = numbers
            continue
        for name, function in PASSES:
            if where.split(" [")[0].endswith("::" + function):
                if name not in counts or numbers[0] > counts[name][0]:
                    counts[name] = numbers
    if "step" not in counts:
        raise ValueError("callgrind_annotate printed no PROGRAM TOTALS")
    return counts


def count_once(binary, bench_args, collect, ll_bytes, folder):
    out = os.path.join(folder, "callgrind.out")
    valgrind = os.environ.get("VALGRIND", "valgrind")
    annotate = os.environ.get("CALLGRIND_ANNOTATE", "callgrind_annotate")
    command = [valgrind, "--tool=callgrind", "--cache-sim=yes", "--D1=49152,12,64",
               f"--LL={ll_bytes},16,64", f"--toggle-collect={collect}",
               f"--callgrind-out-file={out}", binary] + bench_args
    results = run_bench(command)
    if len(results) != 1:
        raise RuntimeError(
            f"{binary}: {len(results)} RESULT lines; filter the benchmark to one case")
    (case, (particles, steps, _, state)), = results.items()
    shown = run_checked([annotate, "--inclusive=yes", "--show=Ir,DLmr,DLmw", out])
    return case, particles * steps, state, parse_annotation(shown.stdout)


def main(argv):
    parser = builds_parser(__doc__)
    parser.add_argument("--collect", default="*ShearCellRun::advance*",
                        help="the function whose calls are counted")
    parser.add_argument("--ll", type=int, default=1 << 20, help="modelled last-level cache, bytes")
    options, bench_args, labels = parse_builds(parser, argv)
    counted = []
    for binary in options.binaries:
        with tempfile.TemporaryDirectory() as folder:
            counted.append(count_once(binary, bench_args, options.collect, options.ll, folder))
    case = counted[0][0]
    print(f"{case[0]}/threads:{case[1]}, per particle-step (last level {options.ll} bytes): "
          f"instructions, misses read + written")
    names = ["step"] + [name for name, _ in PASSES]
    for label, (_, work, state, counts) in zip(labels, counted):
        parts = []
        for name in names:
            if name in counts:
                ir, read, written = (value / work for value in counts[name])
                parts.append(f"{name} {ir:.1f}, {read:.2f} + {written:.2f}")
        print(f"  {label} (state {state}): " + "; ".join(parts))
    base_label, (_, base_work, _, base) = labels[0], counted[0]
    for label, (_, work, _, counts) in zip(labels[1:], counted[1:]):
        ratios = []
        for name in names:
            if name in counts and name in base and base[name][0] > 0:
                instructions = (counts[name][0] / work) / (base[name][0] / base_work)
                base_misses = (base[name][1] + base[name][2]) / base_work
                these_misses = (counts[name][1] + counts[name][2]) / work
                # "-": the first build has none to compare with.
                misses = f"{these_misses / base_misses:.3f}" if base_misses > 0 else "-"
                ratios.append(f"{name} {instructions:.3f}, {misses}")
        print(f"  {label} / {base_label}: instructions, misses: " + "; ".join(ratios))
    states = {state for _, _, state, _ in counted}
    if len(states) > 1:
        print(f"  the builds' states differ: "
              f"{'; '.join(f'{l} {s}' for l, (_, _, s, _) in zip(labels, counted))}")
        return 0 if options.other_bits else 2
    return 0


if __name__ == "__main__":
    run_script(main, "count_instructions.py")
