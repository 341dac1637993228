#!/usr/bin/env python3
"""Compare the task results of two millflow databases (e.g. one campaign before and after a
refactoring): tasks (key, kind, kind_version, params, status, parent), the DAG edges, results
(JSON), artifacts (name, SHA-256, size) and every view's rows. Timing, host, code version,
attempts, logs and status history are left out: they describe a run, not its results.

Usage: compare_stores.py BEFORE.db AFTER.db   (exit status 0 when identical, 1 otherwise)
"""
import sqlite3
import sys

QUERIES = {
    "tasks": "SELECT key, kind, kind_version, params, status, parent_key FROM tasks",
    "edges": "SELECT downstream, position, upstream FROM edges",
    "results": "SELECT task_key, result FROM results",
    "artifacts": "SELECT task_key, name, sha256, size FROM artifacts",
}


def rows(db, sql):
    return sorted(tuple("" if v is None else str(v) for v in row) for row in db.execute(sql))


def views(db):
    return [name for (name,) in db.execute(
        "SELECT name FROM sqlite_master WHERE type = 'view' ORDER BY name")]


def main(before_path, after_path):
    before = sqlite3.connect(f"file:{before_path}?mode=ro", uri=True)
    after = sqlite3.connect(f"file:{after_path}?mode=ro", uri=True)
    queries = dict(QUERIES)
    names = views(before)
    if names != views(after):
        print(f"views differ: {names} vs {views(after)}")
        return 1
    for name in names:
        queries[f"view {name}"] = f'SELECT * FROM "{name}"'
    differences = 0
    for label, sql in queries.items():
        a, b = rows(before, sql), rows(after, sql)
        only_before, only_after = set(a) - set(b), set(b) - set(a)
        status = "identical" if a == b else "DIFFERENT"
        print(f"{label}: {len(a)} vs {len(b)} rows, {status}")
        if a != b:
            differences += 1
            for row in sorted(only_before)[:3]:
                print(f"  only in {before_path}: {str(row)[:300]}")
            for row in sorted(only_after)[:3]:
                print(f"  only in {after_path}: {str(row)[:300]}")
    return 1 if differences else 0


if __name__ == "__main__":
    if len(sys.argv) != 3:
        sys.exit(__doc__)
    sys.exit(main(sys.argv[1], sys.argv[2]))
