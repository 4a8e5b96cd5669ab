#!/usr/bin/env python3
"""The dependency picture of docs/architecture.md#dependencies, checked on every #include.

A library includes only what sits below it; only programs (server/main.cpp, client/cli,
client/load/main.cpp, tools/) cross between the server and the client. Each broken rule is
printed as file:line with the rule it breaks; the exit status is 1 if any is found.
usage: layering_test.py REPOSITORY-ROOT
"""
import pathlib
import re
import sys

INCLUDE = re.compile(r'^\s*#\s*include\s*[<"]([^>"]+)[>"]')
# The server's own headers are named by their concern's folder (server/CMakeLists.txt).
SERVER_HEADERS = re.compile(r'^(rpc|frames|shm|gpu|socket|security|observability|options|threads)/')
PROTO = re.compile(r'^(skinserve/v1/|skinserve/wire/|grpc|grpcpp/|google/protobuf/)')
PROGRAM_OPTIONS = re.compile(r'^skinserve/cli/')
TOOLS = re.compile(r'^(upload_attack\.h|alloc_counter\.h|paper_tables\.h|workload_cache\.h)')


def forbidden(path: str, header: str):
    """Why `path` may not include `header`, or None if it may."""
    is_main = path in ('server/main.cpp', 'client/load/main.cpp') or path.startswith(
        ('client/cli/', 'tools/'))
    if PROGRAM_OPTIONS.match(header) and not is_main and not path.startswith('tools/cli/'):
        return 'the programs\' option code (tools/cli) is for mains only'
    if path.startswith('core/'):
        if PROTO.match(header):
            return 'core/ knows no wire, gRPC or protobuf'
        if SERVER_HEADERS.match(header) or header.startswith(('skinserve/client/', 'skinserve/render/')):
            return 'core/ includes nothing of server/ or client/'
        if TOOLS.match(header):
            return 'core/ includes nothing of tools/'
        if path.startswith(('core/engine/', 'core/model/', 'core/encoding/', 'core/animation/')) and \
                header.startswith(('skinserve/character/', 'skinserve/reference/')):
            return 'what the server runs carries no glTF import and no test references'
    if path.startswith('client/') and not is_main:
        if SERVER_HEADERS.match(header):
            return 'the client library includes nothing of server/'
        if TOOLS.match(header):
            return 'the client library includes nothing of tools/'
    if path.startswith('server/') and path != 'server/main.cpp':
        if header.startswith(('skinserve/client/', 'skinserve/render/', 'skinserve/character/',
                              'skinserve/reference/')):
            return 'the server library includes nothing of client/ (only programs cross)'
        if TOOLS.match(header):
            return 'the server library includes nothing of tools/'
    if path.startswith('proto/') and (SERVER_HEADERS.match(header) or
                                      header.startswith('skinserve/client/')):
        return 'the wire conversions include nothing of server/ or client/'
    return None


def main() -> int:
    root = pathlib.Path(sys.argv[1] if len(sys.argv) > 1 else '.').resolve()
    checked = 0
    broken = []
    for folder in ('core', 'proto', 'server', 'client', 'tools'):
        for source in sorted((root / folder).rglob('*')):
            if source.suffix not in ('.h', '.hpp', '.cpp', '.cc', '.c') or not source.is_file():
                continue
            path = source.relative_to(root).as_posix()
            for number, line in enumerate(source.read_text(encoding='utf-8').splitlines(), 1):
                match = INCLUDE.match(line)
                if not match:
                    continue
                checked += 1
                why = forbidden(path, match.group(1))
                if why:
                    broken.append(f'{path}:{number}: #include "{match.group(1)}": {why}')
    for line in broken:
        print(line)
    # A walk that found nothing to check is itself a failure (a wrong root, moved folders).
    if checked < 500:
        print(f'layering: only {checked} includes found under {root}: wrong root?')
        return 1
    print(f'layering: {checked} includes checked, {len(broken)} broken')
    return 1 if broken else 0


if __name__ == '__main__':
    sys.exit(main())
