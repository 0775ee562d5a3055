"""The campaign's folder: the campaign file and one SQLite database of finished episodes.

Every finished chunk of episodes is written to ``episodes.sqlite`` (stdlib :mod:`sqlite3`, in
WAL mode) in one transaction, so a crash leaves each chunk either whole or absent; the table
``episodes`` holds one row per episode (``episode`` its id, ``row`` its table row as JSON).
``--resume`` runs only the episodes without a row, so an interrupted campaign neither loses
nor repeats an episode, and a killed run loses only the chunks still running.

A folder of the earlier layout (``episodes/NNNNNN.json``, one file per episode) is converted
when it is resumed: its rows are read and checked first (a file that is not a whole row is
refused, with nothing written), then written to the database in one transaction, and the
JSON files (and the ``*.tmp`` files an interrupted write left) are removed.
"""
from __future__ import annotations

import json
import sqlite3
from collections.abc import Iterable, Mapping
from pathlib import Path
from typing import Any

from ..errors import CampaignError

CAMPAIGN_FILE = 'campaign.yaml'
DATABASE = 'episodes.sqlite'
JSON_FOLDER = 'episodes'   # the earlier layout, one file per episode
SCHEMA = 'CREATE TABLE IF NOT EXISTS episodes (episode INTEGER PRIMARY KEY, row TEXT NOT NULL)'


class EpisodeStore:
    """The rows of a campaign's finished episodes, in ``out/episodes.sqlite``."""

    def __init__(self, out: Path) -> None:
        self.out = out
        self.path = out / DATABASE
        self._db: sqlite3.Connection | None = None

    def check(self, text: str, resume: bool) -> None:
        """Refuse a folder the campaign ``text`` cannot be written to (writes nothing).

        Raises
        ------
        CampaignError
            If ``out`` is not empty (and not ``resume``), holds another campaign, or holds a
            row that cannot be read.
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
            json_rows_by_id(out / JSON_FOLDER)
        elif out.is_dir() and any(out.iterdir()):
            raise CampaignError(f"--out '{out}' is not empty; use --resume to continue the "
                                'campaign in it')

    def create(self, text: str, resume: bool) -> None:
        """Make the folder for the campaign ``text``; with ``resume``, open the one there.

        With ``resume``, a folder of the earlier JSON layout is converted (see the module).

        Raises
        ------
        CampaignError
            As :meth:`check`, or if the folder cannot be written.
        """
        self.check(text, resume)
        out = self.out
        if resume:
            old = json_rows(out / JSON_FOLDER)   # checked before anything is written
            self._connect()
            if old:
                self.write(old)
            remove_json_layout(out / JSON_FOLDER)
            return
        try:
            out.mkdir(parents=True, exist_ok=True)
            (out / CAMPAIGN_FILE).write_text(text, encoding='utf-8')
        except OSError as exc:
            raise CampaignError(f"--out '{out}' cannot be written: {exc.strerror}") from None
        self._connect()

    def _connect(self) -> sqlite3.Connection:
        if self._db is None:
            try:
                db = sqlite3.connect(self.path, timeout=30.0)
                db.execute('PRAGMA journal_mode=WAL')
                db.execute('PRAGMA synchronous=NORMAL')   # WAL: a killed process loses nothing
                db.execute(SCHEMA)
                db.commit()
            except sqlite3.Error as exc:
                raise CampaignError(f"'{self.path}' is not a campaign database: {exc}") from None
            self._db = db
        return self._db

    def close(self) -> None:
        """Close the database (the rows are already committed)."""
        if self._db is not None:
            self._db.close()
            self._db = None

    def done(self) -> set[int]:
        """Return the ids of the episodes whose row is stored."""
        if self._db is None and not self.path.is_file():
            return set(json_rows_by_id(self.out / JSON_FOLDER))
        return {i for (i,) in self._connect().execute('SELECT episode FROM episodes')}

    def write(self, rows: Iterable[dict[str, Any]]) -> None:
        """Store the rows of one finished chunk, in one transaction."""
        db = self._connect()
        with db:
            db.executemany('INSERT OR IGNORE INTO episodes (episode, row) VALUES (?, ?)',
                           [(int(r['episode']), json.dumps(r)) for r in rows])

    def read(self, episode: int) -> dict[str, Any]:
        """Return the stored row of episode ``episode``."""
        if self._db is None and not self.path.is_file():
            found = json_rows_by_id(self.out / JSON_FOLDER).get(episode)
        else:
            hit = self._connect().execute('SELECT row FROM episodes WHERE episode = ?',
                                          (episode,)).fetchone()
            found = None if hit is None else json.loads(hit[0])
        if found is None:
            raise CampaignError(f"episode {episode} has no result in '{self.out}'")
        return found

    def rows(self, known: Mapping[int, dict[str, Any]] | None = None) -> list[dict[str, Any]]:
        """Return every stored row, by episode id.

        A row in ``known`` (by episode id: rows this process has just stored) is taken from
        it instead of decoded again; it holds the same values, a row's cells being numbers,
        booleans and strings, which JSON keeps as they are.
        """
        if self._db is None and not self.path.is_file():
            old = json_rows_by_id(self.out / JSON_FOLDER)
            return [old[i] for i in sorted(old)]
        known = known or {}
        return [known[i] if i in known else json.loads(r) for (i, r) in self._connect().execute(
            'SELECT episode, row FROM episodes ORDER BY episode')]

    def passed(self) -> int:
        """Return how many stored episodes passed."""
        return sum(1 for r in self.rows() if r['passed'])


def json_rows_by_id(folder: Path) -> dict[int, dict[str, Any]]:
    """Return the rows of the earlier layout's ``folder`` by episode id (none if absent).

    Raises
    ------
    CampaignError
        If a file is not a whole row (written by something else, or cut short).
    """
    rows: dict[int, dict[str, Any]] = {}
    if not folder.is_dir():
        return rows
    for path in sorted(folder.glob('*.json')):
        if not path.stem.isdigit():
            continue
        try:
            row = json.loads(path.read_text(encoding='utf-8'))
        except (OSError, UnicodeDecodeError, json.JSONDecodeError):
            row = None
        if not isinstance(row, dict) or row.get('episode') != int(path.stem):
            raise CampaignError(f"'{path}' is not a whole episode row; delete it and --resume "
                                f'runs episode {int(path.stem)} again')
        rows[int(path.stem)] = row
    return rows


def json_rows(folder: Path) -> list[dict[str, Any]]:
    """Return the rows of the earlier layout's ``folder``, by episode id."""
    by_id = json_rows_by_id(folder)
    return [by_id[i] for i in sorted(by_id)]


def remove_json_layout(folder: Path) -> None:
    """Remove the earlier layout's files (rows now in the database, ``*.tmp`` leftovers)."""
    if not folder.is_dir():
        return
    for path in [*folder.glob('*.json'), *folder.glob('*.tmp')]:
        path.unlink(missing_ok=True)
    try:
        folder.rmdir()
    except OSError:   # it holds files the campaign did not write: leave them
        pass
