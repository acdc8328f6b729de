"""The ``fusion-planner`` command: planning, simulation and benchmarks without ROS.

Each sub-command lives in its own module exposing ``add_parser(subparsers)``
(which registers the sub-command and sets ``func``) and ``run(args) -> int``.
Exit status: 0 success, 1 the job ran but failed (no path, goal not
reached), 2 bad input. Bad input never prints a traceback.
"""

import argparse
import importlib
import logging
import os
import sys

from fusion_planner.core.errors import PlanningError

#: Modules of the sub-commands, in the order ``--help`` lists them.
COMMANDS = (
    'fusion_planner.cli.plan_command',
    'fusion_planner.cli.bench_command',
    'fusion_planner.cli.demo_command',
    'fusion_planner.cli.sim_command',
)

EXIT_OK, EXIT_FAILED, EXIT_BAD_INPUT = 0, 1, 2


class CommandParser(argparse.ArgumentParser):
    """An argument parser whose sub-commands refuse unknown options themselves.

    argparse hands the options a sub-command does not know back to the
    top-level parser, which then prints its own usage; here the innermost
    sub-command that got them reports them with its usage (exit 2).
    Sub-parsers inherit the class.
    """

    def parse_known_args(self, args=None, namespace=None):
        namespace, unknown = super().parse_known_args(args, namespace)
        if unknown:
            self.error(f'unrecognized arguments: {" ".join(unknown)}')
        return namespace, unknown


def build_parser():
    """The argument parser with every sub-command registered."""
    parser = CommandParser(
        prog='fusion-planner',
        description='Improved A* + improved APF path planning (paper reproduction, '
                    'simulation, benchmarks).')
    parser.add_argument('--verbose', action='store_true', help='log debug messages')
    subparsers = parser.add_subparsers(dest='command', metavar='COMMAND', required=True)
    for name in COMMANDS:
        importlib.import_module(name).add_parser(subparsers)
    return parser


def main(argv=None):
    """Entry point of ``fusion-planner``; returns the exit status."""
    parser = build_parser()
    args = parser.parse_args(argv)
    logging.basicConfig(level=logging.DEBUG if args.verbose else logging.WARNING,
                        format='%(levelname)s %(name)s: %(message)s')
    try:
        return args.func(args)
    except PlanningError as err:
        print(f'error: {err}', file=sys.stderr)
        return EXIT_BAD_INPUT
    except KeyboardInterrupt:
        return 130
    except BrokenPipeError:
        # The reader left early (`| head`): silence the flush at exit.
        os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())
        return EXIT_OK


if __name__ == '__main__':
    sys.exit(main())
