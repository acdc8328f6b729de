"""One output-path policy for every command: missing folders are made, unwritable paths refused.

A path that cannot be written is refused before any work, with one line on
stderr and exit status 2, by every command and option that writes a file.
"""

import pathlib

import pytest

from conftest import REPO
from fusion_planner.cli.main import main
from fusion_planner.cli.output_paths import OutputPathError, prepare_file, prepare_folder

PAPER_MAP = str(REPO / 'config' / 'maps' / 'paper.yaml')
FIG5A = str(REPO / 'config' / 'scenarios' / 'fig5a.yaml')
PLAN = ['plan', '--map', PAPER_MAP, '--start', '1.5', '1.5', '--goal', '19.5', '19.5']

#: Every command line that writes a file or folder; PATH is the output.
WRITERS = [
    [*PLAN, '--plot', 'PATH'],
    [*PLAN, '--json', '--plot', 'PATH'],
    ['sim', '--scenario', FIG5A, '--plot', 'PATH'],
    ['sim', '--scenario', FIG5A, '--gif', 'PATH'],
    ['bench', 'paper', '--plot', 'PATH'],
    ['bench', 'peers', '--quick', '--no-progress', '--suites', 'random', '--planners', 'astar',
     '--plot', 'PATH'],
    ['bench', 'peers', '--quick', '--no-progress', '--suites', 'random', '--planners', 'astar',
     '--json-out', 'PATH'],
    ['demo', '--plot', 'PATH'],
    ['demo', '--no-plot', '--plot', 'PATH', '--gif', 'PATH'],  # --gif PATH
    ['demo', '--no-plot', '--no-gif', '--record', 'PATH'],
]


def test_missing_folders_are_made(tmp_path):
    target = tmp_path / 'a' / 'b' / 'run.png'
    assert prepare_file(target, '--plot') == target
    assert target.parent.is_dir() and not target.exists()
    assert prepare_folder(tmp_path / 'c' / 'd', '--plot').is_dir()
    assert prepare_file('relative.png', '--plot') == pathlib.Path('relative.png')


@pytest.mark.parametrize('make, words', [
    (lambda root: (root / 'file').write_text('x') and root / 'file' / 'run.png',
     'is not a folder'),
    (lambda root: (root / 'file').write_text('x') and root / 'file' / 'deeper' / 'run.png',
     'is not a folder'),
    (lambda root: (root / 'folder').mkdir() or root / 'folder', 'it is a folder'),
])
def test_unwritable_files_are_refused(tmp_path, make, words):
    with pytest.raises(OutputPathError, match=words):
        prepare_file(make(tmp_path), '--plot')


def test_a_folder_below_a_file_is_refused(tmp_path):
    (tmp_path / 'file').write_text('x')
    with pytest.raises(OutputPathError, match='is not a folder'):
        prepare_folder(tmp_path / 'file' / 'figures', '--plot')
    with pytest.raises(OutputPathError, match='is not a folder'):
        prepare_folder(tmp_path / 'file', '--plot')


def test_a_folder_that_cannot_be_made_is_refused(tmp_path):
    too_long = tmp_path / ('x' * 300) / 'run.png'  # longer than any file-name limit
    with pytest.raises(OutputPathError, match='File name too long'):
        prepare_file(too_long, '--plot')


@pytest.mark.parametrize('argv', WRITERS, ids=lambda argv: ' '.join(
    a for a in argv if a.startswith('--') or a in ('plan', 'sim', 'bench', 'demo', 'paper',
                                                    'peers')))
def test_every_command_refuses_a_path_below_a_file_before_any_work(capsys, tmp_path, argv):
    blocker = tmp_path / 'taken'
    blocker.write_text('a file, not a folder')
    argv = [a.replace('PATH', str(blocker / 'out' / 'result.png')) for a in argv]
    status = main(argv)
    out, err = capsys.readouterr()
    assert status == 2
    assert out == ''  # nothing ran
    lines = err.splitlines()
    assert len(lines) == 1 and lines[0].startswith('error: cannot write --'), err
    assert f'{blocker} is not a folder' in lines[0]
