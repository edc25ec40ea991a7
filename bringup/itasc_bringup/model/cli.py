"""``itasc-model``: the application model without running it (paper §4.2).

    itasc-model schema [--out FILE]     the JSON Schema of an application model file
    itasc-model check MODEL...          validate models (names or paths), includes resolved
    itasc-model docs [--out FILE]       write the model reference (default docs/model.md)
    itasc-model configuration DUMP --name NAME
                                        a named configuration from `ros2 param dump` of running
                                        Configurators (CC, Rows, Monitors), to paste into the model

``check`` exits 2 at the first wrong model, with the message the bootstrap would give (file, path
inside it, what was expected); nothing is started (no node, no DDS participant).
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

__all__ = ['main']


def _check(models: list[str]) -> int:
    from itasc_core.composition.loader import ModelError
    from itasc_core.composition.model import walk

    from ..apps import load_composition, resolve_app
    for model in models:
        try:
            composition = load_composition(model)
        except ModelError as err:
            print(f'error: {err}', file=sys.stderr)
            return 2
        composites = list(walk(composition))
        entities = sum(len(c.leaves) for _, c in composites)
        print(f'{resolve_app(model)}: ok ({len(composites)} composites, {entities} entities)')
    return 0


def _configuration(dump: str, name: str) -> int:
    import yaml
    from pydantic import ValidationError

    from .dump import configuration_of
    try:
        configuration = configuration_of(yaml.safe_load(Path(dump).read_text()))
    except (OSError, yaml.YAMLError, ValueError, ValidationError) as err:
        print(f'error: {dump}: {err}', file=sys.stderr)
        return 2
    sys.stdout.write(yaml.safe_dump({'configurations': {name: configuration}}, sort_keys=False))
    return 0


def _write(text: str, out: str | None) -> None:
    if out is None:
        sys.stdout.write(text)
        return
    path = Path(out)
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(text)
    print(f'wrote {path}', file=sys.stderr)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog='itasc-model', description=__doc__.split('\n\n')[0])
    commands = parser.add_subparsers(dest='command', required=True)
    schema = commands.add_parser('schema', help='print the JSON Schema of an application model file')
    schema.add_argument('--out', help='write it to this file instead')
    check = commands.add_parser('check', help='validate models without starting anything')
    check.add_argument('models', nargs='+', metavar='MODEL', help='application name or model file')
    docs = commands.add_parser('docs', help='write the model reference (Markdown)')
    docs.add_argument('--out', default='docs/model.md', help='where (default: %(default)s; - for stdout)')
    configuration = commands.add_parser('configuration',
                                        help='a named configuration from `ros2 param dump` of Configurators')
    configuration.add_argument('dump', metavar='DUMP', help='the YAML file ros2 param dump wrote')
    configuration.add_argument('--name', required=True, help='the configuration\'s name')
    args = parser.parse_args(argv)

    if args.command == 'check':
        return _check(args.models)
    if args.command == 'configuration':
        return _configuration(args.dump, args.name)
    from .locations import config_dirs
    from .reference import json_schema, markdown
    if args.command == 'schema':
        _write(json.dumps(json_schema(), indent=2, allow_nan=False) + '\n', args.out)
    else:
        # the repository's config/ when running from source (last), else the installed one
        _write(markdown(examples=config_dirs()[-1]), None if args.out == '-' else args.out)
    return 0


if __name__ == '__main__':
    sys.exit(main())
