"""What the comparison scripts of this folder share: their command line's `--` split, the
repository root (relative stage paths are taken from it) and the CPU seconds of one
nimbus run."""
import os, resource, subprocess

# Two levels above this file's folder.
ROOT = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))


def split_extra(argv):
    """(arguments, extra render arguments): what follows a `--` goes to every render."""
    if "--" in argv:
        i = argv.index("--")
        return argv[:i], argv[i + 1:]
    return argv, []


def render_cpu(cmd):
    """Runs `cmd` (a nimbus command line) from the repository root and returns its CPU
    seconds, user + system, from getrusage of the children."""
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    subprocess.run(cmd, check=True, capture_output=True, cwd=ROOT)
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    return after.ru_utime - before.ru_utime + after.ru_stime - before.ru_stime
