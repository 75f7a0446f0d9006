import sys

try:
    from harness.cli import main
except KeyboardInterrupt:  # Ctrl-C while the modules load
    print("harness: interrupted", file=sys.stderr)
    sys.exit(130)

sys.exit(main())
