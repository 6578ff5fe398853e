"""Runs a command and writes the peak resident memory of its process tree (KiB: the
largest of the command and every descendant it waited for, `getrusage(RUSAGE_CHILDREN)`)
to a file; exits with the command's status, its output passed through.

    python peak_rss.py OUT_FILE COMMAND [ARGS...]
"""

import resource
import subprocess
import sys


def main():
    out, cmd = sys.argv[1], sys.argv[2:]
    status = subprocess.run(cmd).returncode
    with open(out, "w") as f:
        f.write(str(resource.getrusage(resource.RUSAGE_CHILDREN).ru_maxrss))
    sys.exit(status if status >= 0 else 128 - status)


if __name__ == "__main__":
    main()
