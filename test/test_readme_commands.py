"""README.md's fresh-machine commands and .ci/run must not drift apart."""

import re

from conftest import REPO


def _readme_commands():
    text = (REPO / 'README.md').read_text()
    blocks = re.findall(r'```(?:bash|sh)\n(.*?)```', text, flags=re.S)
    return [line.strip() for block in blocks for line in block.splitlines() if line.strip()]


def test_ci_runs_exactly_the_readme_test_command():
    commands = [c for c in _readme_commands() if 'pytest' in c]
    assert len(commands) == 1, f'README.md must give one test command, found {commands}'
    ci_lines = [line.strip() for line in (REPO / '.ci' / 'run').read_text().splitlines()]
    assert commands[0] in ci_lines


def test_readme_has_a_demo_command_that_sets_up_and_runs():
    commands = [c for c in _readme_commands() if 'fusion-planner demo' in c]
    assert commands, 'README.md must give the closed-loop demo command'
    assert 'pip install' in commands[0]
