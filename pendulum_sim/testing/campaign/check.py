"""Refuse a campaign before its first episode when no episode could run it.

Parsing (:mod:`.spec`) checks the file's own form; this check needs the scene and the drawn
values of an episode (:mod:`.scenarios`, :mod:`.episode`), which sit above the parser.
"""
from __future__ import annotations

import socket

from ..errors import CampaignError, TestingError
from ..scene import with_overrides
from .episode import scene_base  # read once per process, for the episodes too
from .scenarios import episode_scenario
from .spec import CampaignSpec


def check_values(spec: CampaignSpec) -> None:
    """Refuse, before any episode runs, a scene or parameter values no episode could run with.

    The scene is read, and the node's checks run on episode 0's values and on episode 0 with
    the lists' entries ``i`` in their places, all lists together as episode ``i`` takes them
    (lists of one value per episode may belong together, as a body's m, l and inertia do),
    for the first 100 entries: what would fail every episode fails here instead, with the
    reason an episode would give.
    """
    try:
        base = scene_base(spec.scene)
        first = episode_scenario(spec, 0).values
        with_overrides(base, first)
        lists = [(name, space) for name, space in spec.parameters if isinstance(space, tuple)]
        for i in range(1, min(100, max((len(space) for _, space in lists), default=0))):
            with_overrides(base, {**first, **{name: space[i % len(space)]
                                              for name, space in lists}})
    except TestingError as exc:
        raise CampaignError(str(exc).splitlines()[0]) from None


def check_live_port(spec: CampaignSpec, port: int) -> None:
    """Refuse ``--foxglove-port`` when the episodes could not listen on it (it is in use now, on
    the scene's ``foxglove_host``): every episode would fail with that reason."""
    try:
        host = str(scene_base(spec.scene)['foxglove_host'])
        family = socket.getaddrinfo(host, port, type=socket.SOCK_STREAM)[0][0]
        with socket.socket(family, socket.SOCK_STREAM) as probe:
            # As a server binds (SO_REUSEADDR): only a socket listening there is in the way.
            probe.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
            probe.bind((host, port))
    except TestingError as exc:
        raise CampaignError(str(exc).splitlines()[0]) from None
    except OSError as exc:
        raise CampaignError(f'--foxglove-port: cannot listen on {host}:{port} '
                            f'({exc.strerror or exc})') from None
