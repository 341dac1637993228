#!/usr/bin/env python3
"""Two or more builds of a benchmark program, timed in alternating rounds on one core.

The host's speed drifts by tens of per cent within minutes (docs/benchmarks.md), so a build is
only ever compared with another run in the same minutes: each round runs every build once, the
order rotated from round to round, and the ratio of CPU-seconds is taken per round; its median is
the figure to quote. Reads the "RESULT" lines bench_cells and bench_dem print and checks that the
builds give the same state hash (the same bits) unless told the change moves them.

    bench/compare_builds.py [--rounds N] [--core C] [--label NAME]... BIN BIN... -- BENCH_ARGS...

e.g. the media cell, 20 rounds, an old build against this one:

    bench/compare_builds.py --rounds 20 --core 0 /tmp/old/bench/bench_cells \\
        build/bench/bench_cells -- --cells_cache=DIR --cells_steps=2000 \\
        --benchmark_filter='^le_media_2000/threads:1/' --benchmark_min_time=0

Prints, per case (scene and threads) and build: the median CPU-seconds with their range, the
particle-steps per CPU-second at the median, the state hash, and for every build after the
first the per-round ratios first / this (above 1: this build is faster) with their median.
Exit status 0, 2 when the builds' state hashes differ (without --other-bits), 1 on an error.
"""
import argparse
import shutil
import statistics
import subprocess
import sys
from collections import defaultdict


def parse_results(text):
    """{(scene, threads): (particles, steps, cpu_seconds, hash)} from a run's RESULT lines.

    bench_cells: RESULT scene threads particles steps wall-s cpu-s state HASH
    bench_dem:   RESULT scene threads particles steps wall-s pts/s/core pts/cpu-s MiB contacts HASH
    """
    found = {}
    for line in text.splitlines():
        fields = line.split()
        if not fields or fields[0] != "RESULT":
            continue
        scene, threads = fields[1], int(fields[2])
        particles, steps = int(fields[3]), int(fields[4])
        if len(fields) == 9 and fields[7] == "state":
            cpu_seconds, state = float(fields[6]), fields[8]
        elif len(fields) == 11:
            cpu_seconds, state = particles * steps / float(fields[7]), fields[10]
        else:
            raise ValueError(f"a RESULT line of no known form: {line!r}")
        found[(scene, threads)] = (particles, steps, cpu_seconds, state)
    return found


def run_checked(command):
    """The finished command (its output captured); RuntimeError with its error output if it
    failed."""
    done = subprocess.run(command, capture_output=True, text=True)
    if done.returncode != 0:
        raise RuntimeError(f"{' '.join(command)} exited with {done.returncode}:\n"
                           f"{done.stderr[-2000:]}")
    return done


def run_bench(command):
    """The RESULT lines of a bench program run by `command` (parse_results)."""
    done = run_checked(command)
    return parse_results(done.stdout + "\n" + done.stderr)


def run_once(binary, bench_args, core):
    command = [binary] + bench_args
    if core is not None:
        command = ["taskset", "-c", str(core)] + command
    results = run_bench(command)
    if not results:
        raise RuntimeError(f"{' '.join(command)} printed no RESULT line")
    return results


def summarise(labels, rounds, out):
    """rounds: a list, per round, of {label: results}. Returns whether every case's hashes agree."""
    same_bits = True
    cases = sorted({case for one in rounds for results in one.values() for case in results})
    for case in cases:
        print(f"{case[0]}/threads:{case[1]}", file=out)
        seconds = defaultdict(dict)  # label -> round -> CPU-seconds
        states = defaultdict(set)
        work = None
        for r, one in enumerate(rounds):
            for label, results in one.items():
                if case in results:
                    particles, steps, cpu, state = results[case]
                    seconds[label][r] = cpu
                    states[label].add(state)
                    work = particles * steps
        for label in labels:
            if not seconds[label]:
                print(f"  {label}: no result", file=out)
                continue
            values = sorted(seconds[label].values())
            median = statistics.median(values)
            line = (f"  {label}: CPU-s median {median:.4g} ({values[0]:.4g}-{values[-1]:.4g}), "
                    f"{work / median / 1e6:.3f} M particle-steps per CPU-second, "
                    f"state {' '.join(sorted(states[label]))}")
            print(line, file=out)
        base = labels[0]
        for label in labels[1:]:
            paired = [seconds[base][r] / seconds[label][r] for r in seconds[label]
                      if r in seconds[base]]
            if paired:
                faster = sum(1 for ratio in paired if ratio > 1.0)
                print(f"  {base} / {label} per round: {' '.join(f'{x:.3f}' for x in paired)}; "
                      f"median {statistics.median(paired):.3f}, faster in {faster} of "
                      f"{len(paired)}", file=out)
        all_states = set().union(*states.values())
        if len(all_states) > 1:
            same_bits = False
            print(f"  the builds' states differ: "
                  f"{'; '.join(f'{l} {sorted(states[l])}' for l in labels)}", file=out)
    return same_bits


def builds_parser(description):
    """The arguments of this script and bench/count_instructions.py: the builds' bench programs,
    a name each, --other-bits; the bench program's own arguments follow "--"."""
    parser = argparse.ArgumentParser(
        description=description, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("binaries", nargs="+", metavar="BIN", help="the builds' bench programs")
    parser.add_argument("--label", action="append", default=[],
                        help="a name per build, in order (default: the paths)")
    parser.add_argument("--other-bits", action="store_true",
                        help="the change moves the bits: differing state hashes are no error")
    return parser


def parse_builds(parser, argv):
    """(options, the bench program's arguments, a label per build)."""
    split = argv.index("--") if "--" in argv else len(argv)
    options = parser.parse_args(argv[:split])
    if options.label and len(options.label) != len(options.binaries):
        parser.error(f"{len(options.label)} labels for {len(options.binaries)} builds")
    return options, argv[split + 1:], options.label or options.binaries


def main(argv):
    parser = builds_parser(__doc__)
    parser.add_argument("--rounds", type=int, default=6, help="rounds (default 6)")
    parser.add_argument("--core", type=int, default=None,
                        help="pin every run to this core with taskset (default: no pinning)")
    options, bench_args, labels = parse_builds(parser, argv)
    if len(options.binaries) < 2:
        parser.error("give two builds or more")
    if options.rounds < 1:
        parser.error(f"--rounds {options.rounds}: give at least 1")
    if options.core is not None and shutil.which("taskset") is None:
        parser.error("--core needs taskset (util-linux)")
    rounds = []
    for r in range(options.rounds):
        order = [(r + k) % len(labels) for k in range(len(labels))]
        one = {}
        for k in order:
            one[labels[k]] = run_once(options.binaries[k], bench_args, options.core)
        rounds.append(one)
        print(f"round {r + 1} of {options.rounds} done", file=sys.stderr, flush=True)
    same_bits = summarise(labels, rounds, sys.stdout)
    return 0 if same_bits or options.other_bits else 2


def run_script(main_of_script, name):
    """Exits with what main_of_script(the arguments) returns, or 1 after a line naming the error."""
    try:
        sys.exit(main_of_script(sys.argv[1:]))
    except (RuntimeError, ValueError, OSError) as error:
        print(f"{name}: {error}", file=sys.stderr)
        sys.exit(1)


if __name__ == "__main__":
    run_script(main, "compare_builds.py")
