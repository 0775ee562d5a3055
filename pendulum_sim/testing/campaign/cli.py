"""``pendulum_campaign``: run a robustness campaign, continue one, or rerun one episode.

::

    pendulum_campaign CAMPAIGN.yaml --out DIR [--scheduler ADDRESS] [--workers N] [--resume]
                      [--foxglove-port PORT]
    pendulum_campaign --rerun DIR EPISODE

Exit status: 0 when every episode passed, 1 when some failed (or a rerun differs), 2 for a bad
campaign file or command line (one line on stderr says why), 130 after Ctrl-C (the finished
episodes are kept; ``--resume`` continues).
"""
from __future__ import annotations

import argparse
import math
import sys
import threading
from collections.abc import Sequence
from pathlib import Path
from typing import Any

from pendulum_sim.arguments import add_cluster_options, error_exit, interrupted
from pendulum_sim.joint.foxglove import check_port

from ..errors import CampaignError

PROG = 'pendulum_campaign'
MAX_LINE = 400   # characters of an error line at most (values in it are shortened too)


def build_parser() -> argparse.ArgumentParser:
    """Return the argument parser of ``pendulum_campaign``."""
    parser = argparse.ArgumentParser(
        prog=PROG, description='Run a controller over many scenarios (on Dask) and write the '
        'episode table, summary.md, figures and the recording of every failing episode.')
    parser.add_argument('campaign', nargs='?', metavar='CAMPAIGN.yaml',
                        help='the campaign file')
    parser.add_argument('--out', metavar='DIR', help='output folder (new, or with --resume)')
    add_cluster_options(parser)
    parser.add_argument('--resume', action='store_true',
                        help='continue the interrupted campaign in --out')
    parser.add_argument('--rerun', nargs=2, metavar=('DIR', 'EPISODE'),
                        help='run one episode of the campaign in DIR again and compare')
    parser.add_argument('--no-progress', action='store_true', help='no progress bar')
    parser.add_argument('--foxglove-port', type=int, default=0, metavar='PORT',
                        help='serve the episode being run live to Foxglove on this port '
                        '(1024-65535; one local worker, one episode at a time)')
    return parser


def same(a: Any, b: Any) -> bool:
    """Return True for equal values (NaN equals NaN)."""
    if isinstance(a, float) and isinstance(b, float) and math.isnan(a) and math.isnan(b):
        return True
    return bool(a == b) and type(a) is type(b)


def rerun(folder: Path, episode_text: str) -> int:
    """Rerun one episode and compare it with the stored row; return the exit status."""
    from .episode import RUN_COLUMNS, fault_row
    from .sandbox import Fault, run_chunk
    from .spec import parse_spec
    from .store import CAMPAIGN_FILE, EpisodeStore

    saved = folder / CAMPAIGN_FILE
    if not saved.is_file():
        raise CampaignError(f"--rerun: '{folder}' holds no campaign ({CAMPAIGN_FILE} is "
                            'missing)')
    text = saved.read_text(encoding='utf-8')
    spec = parse_spec(text, CAMPAIGN_FILE)
    try:
        episode = int(episode_text)
    except ValueError:
        raise CampaignError(f'--rerun: EPISODE must be an integer, got {episode_text!r}') \
            from None
    if not 0 <= episode < spec.episodes:
        raise CampaignError(f'--rerun: EPISODE must be in [0, {spec.episodes - 1}], got '
                            f'{episode}')
    stored = EpisodeStore(folder).read(episode)
    got = run_chunk(text, [episode], None, spec.episode_timeout)[0]
    again = fault_row(spec, got.episode, got.reason) if isinstance(got, Fault) else got
    differ = [c for c in again if c not in RUN_COLUMNS and not same(again[c], stored.get(c))]
    verdict = 'passed' if again['passed'] else f'failed: {again["reason"]}'
    if differ:
        print(f'episode {episode} differs from the stored result in ' + ', '.join(
            f'{c} ({stored.get(c)!r} then, {again[c]!r} now)' for c in differ))
        return 1
    print(f'episode {episode} reproduced bit for bit ({verdict})')
    return 0


def main(argv: Sequence[str] | None = None) -> int:
    """Run the command line; return the exit status."""
    parser = build_parser()
    args = parser.parse_args(argv)
    try:
        if args.rerun is not None:
            if args.campaign is not None:
                raise CampaignError('--rerun takes DIR and EPISODE, not a campaign file')
            return rerun(Path(args.rerun[0]), args.rerun[1])
        if args.campaign is None or args.out is None:
            raise CampaignError('give CAMPAIGN.yaml and --out DIR (or --rerun DIR EPISODE)')
        if args.scheduler is not None and args.workers is not None:
            raise CampaignError('--workers sizes the local cluster; it cannot go with '
                                '--scheduler')
        if args.foxglove_port:

            reason = check_port(args.foxglove_port)
            if reason is not None:
                raise CampaignError(f'--foxglove-port: {reason}')
            if args.scheduler is not None or args.workers not in (None, 1):
                raise CampaignError('--foxglove-port serves one episode at a time: it needs '
                                    'the local cluster with --workers 1')
            args.workers = 1
        from .check import check_live_port, check_values
        from .execute import check_address, run_campaign
        from .spec import read_spec
        from .summary import import_writers, write_results

        if args.scheduler is not None:
            check_address(args.scheduler)
        spec = read_spec(args.campaign)
        check_values(spec)
        if args.foxglove_port:
            check_live_port(spec, args.foxglove_port)
        out = Path(args.out)
        importing: list[threading.Thread] = []
        rows = run_campaign(spec, out, scheduler=args.scheduler, workers=args.workers,
                            resume=args.resume, progress=not args.no_progress,
                            foxglove_port=args.foxglove_port,
                            on_submitted=lambda: importing.append(import_writers()))
        for thread in importing:
            thread.join()
        write_results(spec, rows, out)
    except CampaignError as exc:
        return error_exit(PROG, exc, MAX_LINE)
    except KeyboardInterrupt:
        return interrupted(PROG)
    failed = sum(1 for r in rows if not r['passed'])
    print(f'{len(rows)} episodes, {len(rows) - failed} passed; wrote {out / "summary.md"}',
          file=sys.stderr)
    return 1 if failed else 0


if __name__ == '__main__':
    sys.exit(main())
