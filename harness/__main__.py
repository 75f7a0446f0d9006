import signal
import sys

from harness import interrupts

interrupts.install()  # Ctrl-C and SIGTERM while the modules load are an interrupt too
try:
    from harness.cli import main
    code = main()
except KeyboardInterrupt:  # while the modules load, or just after main() returned
    print("harness: interrupted", file=sys.stderr)
    code = 130
# the process ends now: a further signal must not turn the exit code into a death by signal
signal.signal(signal.SIGTERM, signal.SIG_IGN)
signal.signal(signal.SIGINT, signal.SIG_IGN)
sys.exit(code)
