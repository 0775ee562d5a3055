"""The campaign's folder: the campaign file, one file per finished episode, nothing lost.

Each finished episode is written at once to ``episodes/NNNNNN.json`` (to a temporary name, then
renamed, so a crash leaves either the whole file or none). ``--resume`` runs only the episodes
without a file, so an interrupted campaign neither loses nor repeats an episode.
"""
from __future__ import annotations

import json
import os
from pathlib import Path
from typing import Any

from ..errors import CampaignError

CAMPAIGN_FILE = 'campaign.yaml'


class EpisodeStore:
    """The rows of a campaign's finished episodes, one JSON file each, under ``out``."""

    def __init__(self, out: Path) -> None:
        self.out = out
        self.folder = out / 'episodes'

    def create(self, text: str, resume: bool) -> None:
        """Make the folder for the campaign ``text``; with ``resume``, check it is the same one.

        Raises
        ------
        CampaignError
            If ``out`` is not empty (and not ``resume``), or holds another campaign.
        """
        out = self.out
        if out.exists() and not out.is_dir():
            raise CampaignError(f"--out '{out}' exists and is not a folder")
        saved = out / CAMPAIGN_FILE
        if resume:
            if not saved.is_file():
                raise CampaignError(f"--resume: '{out}' holds no campaign ({CAMPAIGN_FILE} is "
                                    'missing)')
            if saved.read_text(encoding='utf-8') != text:
                raise CampaignError(f"--resume: '{out}' holds another campaign (its "
                                    f'{CAMPAIGN_FILE} differs)')
        elif out.is_dir() and any(out.iterdir()):
            raise CampaignError(f"--out '{out}' is not empty; use --resume to continue the "
                                'campaign in it')
        try:
            self.folder.mkdir(parents=True, exist_ok=True)
            if not resume:
                saved.write_text(text, encoding='utf-8')
        except OSError as exc:
            raise CampaignError(f"--out '{out}' cannot be written: {exc.strerror}") from None

    def path(self, episode: int) -> Path:
        """Return the file of episode ``episode``."""
        return self.folder / f'{episode:06d}.json'

    def done(self) -> set[int]:
        """Return the ids of the episodes whose row is on disk."""
        if not self.folder.is_dir():
            return set()
        return {int(p.stem) for p in self.folder.glob('*.json') if p.stem.isdigit()}

    def write(self, row: dict[str, Any]) -> None:
        """Write one episode's row (atomically)."""
        path = self.path(int(row['episode']))
        tmp = path.with_suffix(f'.{os.getpid()}.tmp')
        tmp.write_text(json.dumps(row), encoding='utf-8')
        os.replace(tmp, path)

    def read(self, episode: int) -> dict[str, Any]:
        """Return the stored row of episode ``episode``."""
        try:
            row: dict[str, Any] = json.loads(self.path(episode).read_text(encoding='utf-8'))
        except FileNotFoundError:
            raise CampaignError(f"episode {episode} has no result in '{self.out}'") from None
        return row

    def rows(self) -> list[dict[str, Any]]:
        """Return every stored row, by episode id."""
        return [self.read(i) for i in sorted(self.done())]
