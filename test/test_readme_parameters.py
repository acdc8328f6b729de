"""README.md's parameter reference lists exactly the parameters the nodes declare.

The three nodes are created (so a parameter declared anywhere counts, not
only in PARAMETER_SPECS) and their declared names compared with the rows of
the tables under "### Parameters" in README.md, one "#### `node`" table per
node. A parameter declared but not documented, or documented but not
declared, fails; the checker itself is shown to catch both on doctored text.
"""

import re

import pytest

from conftest import REPO

rclpy = pytest.importorskip('rclpy')

from fusion_planner.cli import demo_command  # noqa: E402
from fusion_planner.core.simulation.scenario import load_scenario  # noqa: E402
from fusion_planner.ros.simulator import default_scenario_path  # noqa: E402

#: Heading of the parameter reference in README.md.
SECTION = '### Parameters'
#: Parameters rclpy declares on every node by itself (README.md mentions them in prose).
RCLPY_PARAMETERS = frozenset({'use_sim_time', 'start_type_description_service'})

_NODE_HEADING = re.compile(r'^#### `(\w+)`\s*$')
_ROW = re.compile(r'^\|\s*`([\w.]+)`\s*\|')


def documented_parameters(text):
    """``{node: [parameter, ...]}`` of the reference tables in a README text.

    The reference runs from the line :data:`SECTION` to the next heading of
    level 2 or 3; each ``#### `node``` heading starts a node, and each table
    row whose first cell is a name in backquotes names a parameter.

    Raises
    ------
    ValueError
        If the text has no such section.
    """
    lines = text.splitlines()
    if SECTION not in lines:
        raise ValueError(f'no "{SECTION}" heading')
    documented, node = {}, None
    for line in lines[lines.index(SECTION) + 1:]:
        if re.match(r'^#{2,3} ', line):
            break
        heading = _NODE_HEADING.match(line)
        if heading:
            node = heading.group(1)
            documented.setdefault(node, [])
        elif node is not None and _ROW.match(line):
            documented[node].append(_ROW.match(line).group(1))
    return documented


def mismatches(documented, declared):
    """Sentences for every difference between documented and declared parameters.

    Parameters
    ----------
    documented : dict
        ``{node: [parameter, ...]}`` (:func:`documented_parameters`).
    declared : dict
        ``{node: set of parameter}``.

    Returns
    -------
    list of str
        Empty when both agree.
    """
    problems = []
    for node in sorted(set(documented) | set(declared)):
        names = documented.get(node)
        if names is None:
            problems.append(f'node {node} has no parameter table in README.md')
            continue
        if node not in declared:
            problems.append(f'README.md documents parameters of an unknown node {node}')
            continue
        for name in sorted(set(declared[node]) - set(names)):
            problems.append(f'{node}: parameter {name} is declared but not documented')
        for name in sorted(set(names) - set(declared[node])):
            problems.append(f'{node}: parameter {name} is documented but not declared')
        for name in sorted({n for n in names if names.count(n) > 1}):
            problems.append(f'{node}: parameter {name} is documented twice')
    return problems


@pytest.fixture(scope='module')
def declared(context):
    """``{node name: declared parameter names}`` of the three nodes, rclpy's own left out."""
    path = default_scenario_path()
    params = demo_command.node_parameters(load_scenario(path), path, 1.0)
    nodes = demo_command.make_nodes(context, params)
    try:
        return {node.get_name(): set(node.list_parameters([], 0).names) - RCLPY_PARAMETERS
                for node in nodes}
    finally:
        for node in nodes:
            node.destroy_node()


@pytest.fixture(scope='module')
def readme():
    return (REPO / 'README.md').read_text(encoding='utf-8')


def test_readme_documents_exactly_the_declared_parameters(readme, declared):
    assert set(declared) == {'simulator', 'global_planner', 'local_planner'}
    problems = mismatches(documented_parameters(readme), declared)
    assert not problems, '\n'.join(problems)


def test_checker_catches_an_undocumented_parameter(readme, declared):
    doctored = '\n'.join(line for line in readme.splitlines()
                         if not line.startswith('| `obstacle_mark_range` |'))
    assert mismatches(documented_parameters(doctored), declared) == [
        'global_planner: parameter obstacle_mark_range is declared but not documented']


def test_checker_catches_a_documented_parameter_that_is_not_declared(readme, declared):
    doctored = readme.replace('| `publish_goal` |', '| `publish_goals` | false | typo |\n'
                              '| `publish_goal` |', 1)
    assert mismatches(documented_parameters(doctored), declared) == [
        'simulator: parameter publish_goals is documented but not declared']


def test_checker_catches_a_missing_table_and_an_unknown_node():
    documented = documented_parameters('### Parameters\n\n#### `planner`\n\n'
                                       '| parameter | default | meaning |\n|---|---|---|\n'
                                       '| `rate` | 1.0 | rate [Hz] |\n| `rate` | 1.0 | again |\n'
                                       '## Next\n| `ignored` | x | after the section |\n')
    assert documented == {'planner': ['rate', 'rate']}
    assert mismatches(documented, {'planner': {'rate'}, 'simulator': {'scenario'}}) == [
        'planner: parameter rate is documented twice',
        'node simulator has no parameter table in README.md']
    assert mismatches(documented, {}) == [
        'README.md documents parameters of an unknown node planner']
    with pytest.raises(ValueError, match='Parameters'):
        documented_parameters('# README without a reference\n')
