"""Hosts on one machine: Linux network namespaces joined by a veth pair (``TwoHosts``) or on a
switch (``Lan``).

    with TwoHosts() as hosts:
        subprocess.run(hosts.command(0, ['python', ...]), env={**os.environ, **DDS_OVER_THE_LINK})
        hosts.set_link(False)  # pull the cable

Each namespace has its own ``lo`` (up) and one end of the veth pair (``veth0``, a /30 of
private addresses, and a multicast route: with only a /30 there is no route to DDS's discovery
group 239.255.0.1), so the only path between the two is that link. Namespace names are unique
per instance (pid + random suffix): concurrent runs cannot clash, and the addresses exist only
inside the namespaces. Creating them needs root or CAP_NET_ADMIN; ``unavailable_reason`` says
why a machine cannot.
"""

from __future__ import annotations

import json
import os
import secrets
import shutil
import subprocess
from pathlib import Path

CAP_NET_ADMIN = 12
"""Bit of CAP_NET_ADMIN in /proc/self/status CapEff."""
LINK = 'veth0'
ADDRESSES = ('10.213.0.1', '10.213.0.2')
PREFIX_LENGTH = 30
DDS_OVER_THE_LINK = {
    'ROS_AUTOMATIC_DISCOVERY_RANGE': 'SUBNET',
    'FASTRTPS_DEFAULT_PROFILES_FILE': str(Path(__file__).with_name('fastdds_udp.xml')),
}
"""Environment for nodes in the namespaces (beside ROS_DOMAIN_ID): discovery by multicast on the
link instead of localhost only, and the Fast DDS profile fastdds_udp.xml: UDP as the only
transport (two real hosts share no memory, two namespaces share /dev/shm), socket buffers large
enough that a busy receiver does not drop the 1 kHz step topics, and a heartbeat that repairs a
lost datagram within lockstep's wait (docs/robustness.md)."""


def unavailable_reason() -> str | None:
    """Why network namespaces cannot be made here (None: they can)."""
    if shutil.which('ip') is None:
        return 'needs the ip command (iproute2) to create network namespaces'
    if os.geteuid() != 0 and not _has_net_admin():
        return 'needs root or CAP_NET_ADMIN to create network namespaces and a veth pair'
    return None


def _has_net_admin() -> bool:
    for line in Path('/proc/self/status').read_text().splitlines():
        if line.startswith('CapEff:'):
            return bool(int(line.split()[1], 16) >> CAP_NET_ADMIN & 1)
    return False


class Namespaces:
    """Network namespaces made on entering (``_wire`` cables them), all deleted on exit."""

    def __init__(self, hosts: tuple[str, ...], others: tuple[str, ...] = ()) -> None:
        self.names = hosts
        self._made = (*others, *hosts)
        self._created: list[str] = []

    def __enter__(self):
        try:
            for name in self._made:
                _ip('netns', 'add', name)
                self._created.append(name)
            self._wire()
        except BaseException:
            self.remove()
            raise
        return self

    def _wire(self) -> None:
        raise NotImplementedError

    def __exit__(self, *exc: object) -> None:
        self.remove()

    def remove(self) -> None:
        """Delete the namespaces (veth pairs go with them once their processes are gone)."""
        while self._created:
            subprocess.run(['ip', 'netns', 'delete', self._created.pop()], capture_output=True, check=False)

    def command(self, host: int, cmd: list[str]) -> list[str]:
        """``cmd`` run inside host ``host``."""
        return ['ip', 'netns', 'exec', self.names[host], *cmd]


class TwoHosts(Namespaces):
    """Two network namespaces (host 0 and host 1) joined by a veth pair; removed on exit."""

    def __init__(self) -> None:
        tag = f'wbs{os.getpid()}-{secrets.token_hex(3)}'
        super().__init__((f'{tag}-a', f'{tag}-b'))

    def _wire(self) -> None:
        _ip('link', 'add', LINK, 'netns', self.names[0], 'type', 'veth', 'peer', 'name', LINK, 'netns', self.names[1])
        for name, address in zip(self.names, ADDRESSES):
            _ip('-n', name, 'addr', 'add', f'{address}/{PREFIX_LENGTH}', 'dev', LINK)
            _ip('-n', name, 'link', 'set', 'lo', 'up')
            _ip('-n', name, 'link', 'set', LINK, 'up')
            _multicast_route(name)

    def packets_received(self, host: int) -> int:
        """Packets host ``host`` has received on its end of the link."""
        result = subprocess.run(['ip', '-n', self.names[host], '-s', '-j', 'link', 'show', LINK],
                                capture_output=True, text=True, check=True)
        return int(json.loads(result.stdout)[0]['stats64']['rx']['packets'])

    def set_link(self, up: bool) -> None:
        """Bring host 0's end of the link up or down (down on one end is no carrier on both).

        Taking a link down drops its routes; up restores the multicast route, as a host's network
        configuration would.
        """
        _ip('-n', self.names[0], 'link', 'set', LINK, 'up' if up else 'down')
        if up:
            _multicast_route(self.names[0])


class Lan(Namespaces):
    """``count`` hosts (network namespaces) on one switch: a Linux bridge in a namespace of its own,
    each host's ``veth0`` (10.214.0.k/24, k from 1) cabled to it; removed on exit. A host reaches
    every other one over the switch, as on a real LAN, and nothing outside it."""

    SUBNET = '10.214.0'

    def __init__(self, count: int) -> None:
        tag = f'wbl{os.getpid()}-{secrets.token_hex(3)}'
        self.switch = f'{tag}-sw'
        super().__init__(tuple(f'{tag}-{k}' for k in range(count)), (self.switch,))

    def address(self, host: int) -> str:
        return f'{self.SUBNET}.{host + 1}'

    def _wire(self) -> None:
        _ip('-n', self.switch, 'link', 'add', 'br0', 'type', 'bridge')
        _ip('-n', self.switch, 'link', 'set', 'br0', 'up')
        for host, name in enumerate(self.names):
            port = f'port{host}'
            _ip('link', 'add', LINK, 'netns', name, 'type', 'veth', 'peer', 'name', port, 'netns', self.switch)
            _ip('-n', self.switch, 'link', 'set', port, 'master', 'br0')
            _ip('-n', self.switch, 'link', 'set', port, 'up')
            _ip('-n', name, 'addr', 'add', f'{self.address(host)}/24', 'dev', LINK)
            _ip('-n', name, 'link', 'set', 'lo', 'up')
            _ip('-n', name, 'link', 'set', LINK, 'up')


def _multicast_route(namespace: str) -> None:
    _ip('-n', namespace, 'route', 'replace', '224.0.0.0/4', 'dev', LINK)


def _ip(*args: str) -> None:
    result = subprocess.run(['ip', *args], capture_output=True, text=True, check=False)
    if result.returncode != 0:
        raise RuntimeError(f'ip {" ".join(args)}: {result.stderr.strip() or f"exit status {result.returncode}"}')
