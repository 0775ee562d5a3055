"""The campaign tutorial's failing episode fails, with the tutorial's own campaign file and seed.

The page names one episode as the first that fails, its reason, and the commands that look at
its recording and rerun it. The test takes the campaign file from the page, runs it with the
page's command up to that episode (an episode's scenario depends only on the seed and its id,
never on how many episodes the campaign has, so the first N + 1 episodes are those of the
whole campaign), and then runs the page's commands on the folder as written: the example
cannot name an episode that passes, or a recording that does not exist, without this failing.
"""
from __future__ import annotations

import re
from pathlib import Path

import pytest
from doc_pages import TUTORIALS, blocks, run_shell, run_steps

from pendulum_sim.testing.campaign.store import EpisodeStore

pytestmark = [pytest.mark.ros, pytest.mark.slow]   # pendulum_replay publishes over DDS

PAGE = TUTORIALS / 'campaign.md'


def test_the_failing_episode_the_tutorial_names_fails_and_its_commands_run(
        tmp_path: Path) -> None:
    text = PAGE.read_text(encoding='utf-8')
    (campaign,) = [b for b in blocks(PAGE, 'yaml') if b.startswith('# campaign.yaml\n')]
    named = re.search(r'episode (\d+) is the first that fails: .*? with the reason `([^`]+)`',
                      text, re.S)
    assert named is not None, 'the page names no failing episode'
    episode, reason = int(named[1]), named[2]
    (look,) = [b for b in blocks(PAGE, 'bash') if 'failures/episode-' in b]
    # Every command of the block names that episode, and nothing else does.
    assert set(re.findall(r'episode-(\d{6})\.mcap', look)) == {f'{episode:06d}'}
    assert re.findall(r'--rerun results (\d+)', look) == [str(episode)]
    printed = re.search(r'The last command prints\s+`([^`]+)`', text)
    assert printed is not None
    run = next(line for b in blocks(PAGE, 'bash') for line in b.splitlines()
               if line.startswith('pendulum_campaign campaign.yaml --out results'))
    assert run == 'pendulum_campaign campaign.yaml --out results'

    total = int(re.search(r'^episodes: (\d+)', campaign, re.M)[1])   # type: ignore[index]
    assert episode < total
    (tmp_path / 'campaign.yaml').write_text(
        re.sub(r'^episodes: \d+', f'episodes: {episode + 1}', campaign, flags=re.M))
    done = run_shell(run, tmp_path)
    assert done.returncode == 1, done.stderr          # some episode failed
    rows = EpisodeStore(tmp_path / 'results').rows()
    assert [r['episode'] for r in rows] == list(range(episode + 1))
    assert all(r['passed'] for r in rows[:episode])   # the first that fails ...
    assert not rows[episode]['passed'] and rows[episode]['reason'] == reason   # ... and why
    summary = (tmp_path / 'results' / 'summary.md').read_text()
    assert f'| {reason} | failures/episode-{episode:06d}.mcap |' in summary

    (looked,) = run_steps([look], tmp_path)
    assert looked.splitlines()[-1] == printed[1]
    assert (tmp_path / f'ep{episode}' / 'summary.md').is_file()
