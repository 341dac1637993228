"""What the benchmark scripts' tests share: fake programs written to a folder, and a check."""
import os
import stat
import sys


def make_executable(folder, name, text):
    """Writes `text` to folder/name as an executable; returns its path."""
    path = os.path.join(folder, name)
    with open(path, "w") as f:
        f.write(text)
    os.chmod(path, os.stat(path).st_mode | stat.S_IXUSR)
    return path


def expect(condition, message):
    """Ends the test as failed, printing `message`, unless `condition` holds."""
    if not condition:
        print("FAIL:", message)
        sys.exit(1)
