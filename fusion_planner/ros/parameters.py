"""Declared, validated, atomically swapped node parameters (STYLE.md rule 3).

Each node keeps, in its own module, a frozen dataclass of its tunables and a
table of :class:`ParameterSpec` (name, default, description with unit, range,
read-only). :class:`ParameterHandler` does the rest, the same way for every
node:

1. declares every entry with a ``ParameterDescriptor`` (description, range,
   read-only flag, allowed values), so ``--params-file`` overrides apply and
   ``ros2 param describe`` tells the user the unit and the range;
2. reads the values once into the dataclass (its ``__post_init__`` checks
   cross-field consistency at start-up);
3. guards run-time changes: rclpy applies the descriptors first (type, range,
   read-only), then :meth:`ParameterHandler._on_set` checks the allowed
   string values and builds the candidate dataclass, so its ``__post_init__``
   can refuse the change with a reason; only after rclpy stored the values
   does the post-set callback swap the new dataclass in and call the node's
   ``on_change`` hook.

Readers take ``handler.current`` once per callback and use that snapshot: the
swap is a single attribute assignment, so a reader never sees half an update.

Examples
--------
A node module holds::

    @dataclass(frozen=True)
    class Params:
        rate: float = 20.0

    SPECS = (ParameterSpec('rate', 20.0, 'command rate [Hz]', float_range(1.0, 100.0)),)

and its ``__init__`` calls ``self._params = ParameterHandler(self, Params, SPECS)``.
"""

import threading
from dataclasses import dataclass, fields, replace

from rcl_interfaces.msg import (
    FloatingPointRange, IntegerRange, ParameterDescriptor, SetParametersResult)
from rclpy.exceptions import InvalidParameterTypeException, InvalidParameterValueException

from fusion_planner.core.errors import InvalidInput


def float_range(low, high):
    """A ``FloatingPointRange`` ``[low, high]`` (inclusive, no step)."""
    return FloatingPointRange(from_value=float(low), to_value=float(high), step=0.0)


def int_range(low, high, step=1):
    """An ``IntegerRange`` ``[low, high]`` with ``step`` (values ``low + k * step``)."""
    return IntegerRange(from_value=int(low), to_value=int(high), step=int(step))


@dataclass(frozen=True)
class ParameterSpec:
    """One declared parameter.

    Attributes
    ----------
    name : str
        Parameter name, equal to the dataclass field it fills.
    default : bool, int, float or str
        Default value; its Python type is the parameter's ROS type (write
        floats with a decimal point in YAML, or rclpy refuses them).
    description : str
        What it does, with its unit in brackets, e.g. ``'robot radius [m]'``.
    range : FloatingPointRange or IntegerRange, optional
        Inclusive bounds, enforced by rclpy on declaration and on every set.
    read_only : bool
        Settable only at start-up (from the params file); rclpy refuses a
        run-time change with a reason.
    choices : tuple of str
        Allowed values of a string parameter (empty: any string).
    """

    name: str
    default: object
    description: str
    range: object = None
    read_only: bool = False
    choices: tuple = ()

    def descriptor(self):
        """The ``ParameterDescriptor`` declared for this parameter."""
        desc = ParameterDescriptor(description=self.description, read_only=self.read_only)
        if isinstance(self.range, FloatingPointRange):
            desc.floating_point_range = [self.range]
        elif isinstance(self.range, IntegerRange):
            desc.integer_range = [self.range]
        if self.choices:
            desc.additional_constraints = 'one of: ' + ', '.join(self.choices)
        return desc

    def check_choice(self, value):
        """Sentence explaining why ``value`` is not allowed, or None."""
        if self.choices and value not in self.choices:
            return f'{self.name} must be one of {", ".join(self.choices)}, got {value!r}'
        return None


class ParameterHandler:
    """Declares a node's parameters, reads them once, and guards updates.

    Parameters
    ----------
    node : rclpy.node.Node
    params_type : type
        A frozen dataclass; every spec name must be one of its fields.
        Fields without a spec keep their dataclass default.
    specs : sequence of ParameterSpec
    on_change : callable, optional
        ``on_change(old, new)`` called after an accepted run-time change, in
        the thread that set the parameters.

    Raises
    ------
    InvalidInput
        If a spec names no field, or the start-up values (defaults or params
        file) are out of range, of the wrong type, not an allowed choice, or
        refused by the dataclass; one sentence naming the parameter.
    """

    def __init__(self, node, params_type, specs, on_change=None):
        field_names = {f.name for f in fields(params_type)}
        unknown = [s.name for s in specs if s.name not in field_names]
        if unknown:
            raise InvalidInput(
                f'parameter specs name no field of {params_type.__name__}: {unknown}')
        self._node = node
        self._type = params_type
        self._specs = {s.name: s for s in specs}
        self._on_change = on_change
        self._lock = threading.Lock()
        try:
            declared = node.declare_parameters(
                '', [(s.name, s.default, s.descriptor()) for s in specs])
        except InvalidParameterTypeException as err:
            raise InvalidInput(f'a parameter has the wrong type: {err}') from None
        except InvalidParameterValueException as err:
            raise InvalidInput(f'a parameter value is refused: {err}') from None
        values = {p.name: p.value for p in declared}
        for name, value in values.items():
            reason = self._specs[name].check_choice(value)
            if reason:
                raise InvalidInput(reason)
        try:
            self._current = params_type(**values)
        except (TypeError, ValueError) as err:
            raise InvalidInput(f'the parameters are inconsistent: {err}') from None
        node.add_on_set_parameters_callback(self._on_set)
        node.add_post_set_parameters_callback(self._on_post_set)

    @property
    def current(self):
        """The parameters now in force (a frozen dataclass instance)."""
        return self._current

    @property
    def specs(self):
        """The declared specs, in declaration order."""
        return tuple(self._specs.values())

    def _changes(self, parameters):
        """``{field: value}`` of the parameters in ``parameters`` that are ours."""
        return {p.name: p.value for p in parameters if p.name in self._specs}

    def _on_set(self, parameters):
        """Validate a run-time change; rclpy has already checked type, range, read-only."""
        changes = self._changes(parameters)
        if not changes:
            return SetParametersResult(successful=True)
        for name, value in changes.items():
            reason = self._specs[name].check_choice(value)
            if reason:
                return SetParametersResult(successful=False, reason=reason)
        with self._lock:
            try:
                replace(self._current, **changes)
            except (TypeError, ValueError) as err:
                return SetParametersResult(successful=False, reason=str(err))
        return SetParametersResult(successful=True)

    def _on_post_set(self, parameters):
        """Swap in the new dataclass once rclpy has stored the values."""
        changes = self._changes(parameters)
        if not changes:
            return
        with self._lock:
            old = self._current
            try:
                new = replace(old, **changes)
            except (TypeError, ValueError) as err:
                # Only a concurrent change validated against an older state gets here.
                self._node.get_logger().error(f'parameter change not applied: {err}')
                return
            self._current = new
        if self._on_change is not None:
            try:
                self._on_change(old, new)
            except Exception as err:  # noqa: BLE001 - a hook bug must not kill the node
                self._node.get_logger().error(
                    f'applying the new parameters failed: {type(err).__name__}: {err}')
