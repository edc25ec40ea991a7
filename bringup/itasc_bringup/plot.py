"""Placeholder for the `plot` entry point of itasc_bringup (to be replaced by the lead)."""
import sys


def main(argv=None):
    print('itasc_bringup plot: not implemented yet', file=sys.stderr)
    return 1


if __name__ == '__main__':
    sys.exit(main())
