"""The `backlash` command of the package: the program's own code (src/bin/backlash), compiled into the
extension, so that `backlash` behaves as target/release/backlash does."""
import signal
import sys

from . import _backlash


def main():
    # Ctrl-C ends the command at once, as it ends the program (the computation runs in Rust, where Python's
    # own handler would only be seen when it returns).
    signal.signal(signal.SIGINT, signal.SIG_DFL)
    sys.stdout.flush()
    return _backlash.run_cli(["backlash", *sys.argv[1:]])


if __name__ == "__main__":
    sys.exit(main())
