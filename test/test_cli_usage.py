"""A mistyped option is reported with the usage of the sub-command it was given to."""

import pytest

from conftest import REPO
from fusion_planner.cli.main import main

PAPER_MAP = str(REPO / 'config' / 'maps' / 'paper.yaml')


@pytest.mark.parametrize('argv, prog, typo', [
    (['plan', '--map', PAPER_MAP, '--start', '1', '1', '--goal', '2', '2', '--algoritm', 'astar'],
     'fusion-planner plan', '--algoritm astar'),
    (['sim', '--scenario', 'x.yaml', '--controler', 'apf'], 'fusion-planner sim',
     '--controler apf'),
    (['demo', '--time-limt', '3'], 'fusion-planner demo', '--time-limt 3'),
    (['bench', 'paper', '--repaets', '3'], 'fusion-planner bench paper', '--repaets 3'),
    (['bench', 'peers', '--quik'], 'fusion-planner bench peers', '--quik'),
])
def test_mistyped_option_prints_the_sub_command_usage(capsys, argv, prog, typo):
    with pytest.raises(SystemExit) as stop:
        main(argv)
    assert stop.value.code == 2
    err = capsys.readouterr().err
    assert err.startswith(f'usage: {prog} ')
    assert err.endswith(f'{prog}: error: unrecognized arguments: {typo}\n')


def test_unknown_top_level_option_prints_the_top_level_usage(capsys):
    with pytest.raises(SystemExit) as stop:
        main(['--verbsoe', 'plan', '--map', PAPER_MAP, '--start', '1', '1', '--goal', '2', '2'])
    assert stop.value.code == 2
    err = capsys.readouterr().err
    assert err.startswith('usage: fusion-planner [-h]') and '--verbsoe' in err
