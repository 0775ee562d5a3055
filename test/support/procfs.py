"""What /proc says of another process (Linux): the sockets it holds and its resident memory."""
from __future__ import annotations

import os
import re
import socket
from pathlib import Path

TCP_LISTEN = '0A'
"""The state column of /proc/net/tcp{,6} for a listening socket."""


def socket_inodes(pid: int) -> set[str]:
    """Return the inodes of the sockets among process ``pid``'s open files."""
    inodes = set()
    for fd in os.listdir(f'/proc/{pid}/fd'):
        try:
            target = os.readlink(f'/proc/{pid}/fd/{fd}')
        except OSError:  # closed meanwhile
            continue
        if target.startswith('socket:['):
            inodes.add(target[8:-1])
    return inodes


def sockets(pid: int, protocol: str) -> list[tuple[str, int, str]]:
    """Return (local address, port, state) of every ``protocol`` socket process ``pid`` holds.

    ``protocol`` is ``tcp`` or ``udp``; both /proc/<pid>/net/<protocol> (IPv4) and its ``6``
    table are read. Addresses are written as ``socket.inet_ntop`` writes them (``127.0.0.1``,
    ``::1``, ``::ffff:127.0.0.1``); the state is the table's hexadecimal column (TCP_LISTEN).
    """
    inodes = socket_inodes(pid)
    found = []
    for table, family in ((protocol, socket.AF_INET), (f'{protocol}6', socket.AF_INET6)):
        for line in Path(f'/proc/{pid}/net/{table}').read_text().splitlines()[1:]:
            fields = line.split()
            if fields[9] not in inodes:
                continue
            hex_addr, hex_port = fields[1].split(':')
            raw = bytes.fromhex(hex_addr)
            # The kernel prints addresses as 32-bit words in host (little-endian) order.
            addr = b''.join(raw[i:i + 4][::-1] for i in range(0, len(raw), 4))
            found.append((socket.inet_ntop(family, addr), int(hex_port, 16), fields[3]))
    return found


def rss_kib(pid: int) -> int:
    """Return the resident set size of process ``pid`` in KiB."""
    text = Path(f'/proc/{pid}/status').read_text()
    found = re.search(r'^VmRSS:\s+(\d+) kB', text, re.M)
    assert found is not None, 'no VmRSS'
    return int(found.group(1))


def descendants(pid: int) -> set[int]:
    """Return the processes below process ``pid`` (children, theirs, ...), read from /proc."""
    parent_of: dict[int, int] = {}
    for entry in os.listdir('/proc'):
        if not entry.isdigit():
            continue
        try:
            stat = Path(f'/proc/{entry}/stat').read_text()
        except OSError:   # ended meanwhile
            continue
        # The command name, in parentheses, may hold spaces: the fields after it are plain.
        parent_of[int(entry)] = int(stat[stat.rindex(')') + 2:].split()[1])
    found: set[int] = set()
    frontier = {pid}
    while frontier:
        frontier = {child for child, parent in parent_of.items() if parent in frontier} - found
        found |= frontier
    return found
