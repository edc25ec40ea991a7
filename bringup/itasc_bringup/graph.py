"""Placeholder for the `graph` entry point of itasc_bringup (to be replaced by the lead)."""
import sys


def main(argv=None):
    print('itasc_bringup graph: not implemented yet', file=sys.stderr)
    return 1


if __name__ == '__main__':
    sys.exit(main())
