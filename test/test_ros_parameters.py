"""Tests of fusion_planner.ros.parameters: declare, read once, guard, swap."""

from dataclasses import dataclass

import pytest
from rclpy.node import Node
from rclpy.parameter import Parameter

from fusion_planner.core.errors import InvalidInput
from fusion_planner.ros.parameters import ParameterHandler, ParameterSpec, float_range, int_range


@dataclass(frozen=True)
class Limits:
    low: float = 1.0
    high: float = 2.0
    mode: str = 'fast'
    count: int = 4
    untouched: int = 7  # a field without a spec keeps its default

    def __post_init__(self):
        if self.low > self.high:
            raise InvalidInput(f'low {self.low} must not exceed high {self.high}')


SPECS = (
    ParameterSpec('low', 1.0, 'lower limit [m]', float_range(0.0, 10.0)),
    ParameterSpec('high', 2.0, 'upper limit [m]', float_range(0.0, 10.0)),
    ParameterSpec('mode', 'fast', 'speed mode', choices=('fast', 'slow')),
    ParameterSpec('count', 4, 'samples [1]', int_range(4, 16, 4), read_only=True),
)


@pytest.fixture
def make_node(context):
    nodes = []

    def make(**overrides):
        node = Node(f'params_{len(nodes)}', context=context, parameter_overrides=[
            Parameter(k, value=v) for k, v in overrides.items()])
        nodes.append(node)
        return node
    yield make
    for node in nodes:
        node.destroy_node()


def test_declares_with_descriptors_and_reads_once(make_node):
    node = make_node(high=5.0)
    handler = ParameterHandler(node, Limits, SPECS)
    assert handler.current == Limits(high=5.0)
    low = node.describe_parameter('low')
    assert low.description == 'lower limit [m]'
    assert (low.floating_point_range[0].from_value, low.floating_point_range[0].to_value) == (0.0, 10.0)
    assert node.describe_parameter('count').read_only
    assert 'fast' in node.describe_parameter('mode').additional_constraints


@pytest.mark.parametrize('overrides, fragment', [
    (dict(low=11.0), 'refused'),        # out of range
    (dict(low=1), 'wrong type'),        # int for a double
    (dict(mode='medium'), 'one of'),    # not an allowed choice
    (dict(low=3.0), 'must not exceed'),  # the dataclass refuses
])
def test_bad_start_up_values_raise_one_sentence(make_node, overrides, fragment):
    with pytest.raises(InvalidInput, match=fragment):
        ParameterHandler(make_node(**overrides), Limits, SPECS)


def test_spec_without_field_is_refused(make_node):
    with pytest.raises(InvalidInput, match='no field'):
        ParameterHandler(make_node(), Limits, SPECS + (ParameterSpec('nope', 1.0, 'x'),))


def test_runtime_changes_are_validated_then_swapped(make_node):
    node = make_node()
    seen = []
    handler = ParameterHandler(node, Limits, SPECS, on_change=lambda old, new: seen.append((old, new)))
    refused = {
        'low': (Parameter('low', value=3.0), 'must not exceed'),
        'range': (Parameter('high', value=20.0), 'out of range'),
        'choice': (Parameter('mode', value='medium'), 'one of'),
        'read_only': (Parameter('count', value=8), 'read-only'),
    }
    for param, fragment in refused.values():
        result = node.set_parameters([param])[0]
        assert not result.successful and fragment in result.reason
    assert handler.current == Limits() and seen == []

    assert node.set_parameters_atomically([Parameter('high', value=6.0),
                                           Parameter('low', value=5.0)]).successful
    assert handler.current == Limits(low=5.0, high=6.0)
    assert seen[-1] == (Limits(), Limits(low=5.0, high=6.0))
    assert node.get_parameter('low').value == 5.0


def test_a_failing_hook_does_not_propagate(make_node):
    node = make_node()

    def hook(old, new):
        raise RuntimeError('hook bug')

    handler = ParameterHandler(node, Limits, SPECS, on_change=hook)
    assert node.set_parameters([Parameter('mode', value='slow')])[0].successful
    assert handler.current.mode == 'slow'
