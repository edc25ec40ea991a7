"""``itasc-recover``: make a recording that was cut off readable again (SPEC: a fault must leave
the recording readable; paper §7: the recording is how a run is looked at afterwards).

A recorder killed with SIGKILL (or a machine that lost power) leaves an MCAP file without its
summary and footer, which readers such as rosbags refuse. The recorder finishes a chunk every
second, so everything up to the last finished chunk is intact on disk: this command reads the
file as a stream until it ends or breaks off, and writes the schemas, channels, messages and
metadata it found into a complete MCAP file. At most the last second of the run is lost.

    itasc-recover BROKEN.mcap|BAG_FOLDER [-o RECOVERED.mcap]
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from mcap.exceptions import McapError
from mcap.records import Channel, Message, Metadata, Schema
from mcap.stream_reader import StreamReader
from mcap.writer import CompressionType, Writer

__all__ = ['recover', 'main']


def recover(source: Path, target: Path) -> tuple[int, bool]:
    """Copy what ``source`` holds into a complete MCAP file ``target``; returns the number of
    messages and whether ``source`` was cut off."""
    messages, cut_off = 0, False
    schemas: dict[int, int] = {}
    channels: dict[int, int] = {}
    with source.open('rb') as stream, target.open('wb') as out:
        writer = Writer(out, compression=CompressionType.ZSTD)
        writer.start(profile='ros2', library='itasc-recover')
        try:
            for record in StreamReader(stream, skip_magic=False).records:
                if isinstance(record, Schema):
                    schemas[record.id] = writer.register_schema(record.name, record.encoding, record.data)
                elif isinstance(record, Channel) and record.schema_id in schemas:
                    channels[record.id] = writer.register_channel(
                        record.topic, record.message_encoding, schemas[record.schema_id], dict(record.metadata))
                elif isinstance(record, Message) and record.channel_id in channels:
                    writer.add_message(channels[record.channel_id], log_time=record.log_time, data=record.data,
                                       publish_time=record.publish_time, sequence=record.sequence)
                    messages += 1
                elif isinstance(record, Metadata):
                    writer.add_metadata(record.name, dict(record.metadata))
        except (McapError, EOFError, ValueError, OSError):
            cut_off = True  # the file ends inside a record or a chunk: what came before is kept
        writer.finish()
    return messages, cut_off


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog='itasc-recover', description=__doc__.split('\n\n')[0])
    parser.add_argument('mcap', type=Path, help='the MCAP file (or bag folder) of a recording that was cut off')
    parser.add_argument('-o', '--output', type=Path, default=None,
                        help='where to write the recovered file (default: <name>.recovered.mcap)')
    args = parser.parse_args(argv)
    source = args.mcap
    if source.is_dir():  # a bag folder: its MCAP file
        found = sorted(f for f in source.glob('*.mcap') if not f.name.endswith('.recovered.mcap'))
        if len(found) != 1:
            print(f'error: {source}: a bag folder with {len(found)} MCAP files; give the one to recover',
                  file=sys.stderr)
            return 2
        source = found[0]
    if not source.is_file():
        print(f'error: {source}: no such file', file=sys.stderr)
        return 2
    output = args.output or source.with_suffix('.recovered.mcap')
    messages, cut_off = recover(source, output)
    print(f'{output}: {messages} messages recovered' + (' (the original was cut off)' if cut_off else ''))
    return 0


if __name__ == '__main__':
    sys.exit(main())
