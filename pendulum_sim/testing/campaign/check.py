"""Refuse a campaign before its first episode when no episode could run it.

Parsing (:mod:`.spec`) checks the file's own form; this check needs the scene and the drawn
values of an episode (:mod:`.scenarios`, :mod:`.episode`), which sit above the parser.
"""
from __future__ import annotations

from ..errors import CampaignError, TestingError
from ..scene import with_overrides
from .episode import scene_base  # read once per process, for the episodes too
from .scenarios import episode_scenario
from .spec import CampaignSpec


def check_values(spec: CampaignSpec) -> None:
    """Refuse, before any episode runs, a scene or parameter values no episode could run with.

    The scene is read, and the node's checks run on episode 0's values and on episode 0 with
    each entry of a list in its place: what would fail every episode fails here instead,
    with the reason an episode would give.
    """
    try:
        base = scene_base(spec.scene)
        first = episode_scenario(spec, 0).values
        with_overrides(base, first)
        for name, space in spec.parameters:
            if isinstance(space, tuple):
                for value in space[:100]:
                    with_overrides(base, {**first, name: value})
    except TestingError as exc:
        raise CampaignError(str(exc).splitlines()[0]) from None
