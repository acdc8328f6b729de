"""``fusion-planner bench TARGET``: benchmarks, one module per target.

:data:`TARGETS` maps a target name to the module that implements it. Such a
module exposes ``add_arguments(parser)`` (its options) and ``run(args) ->
int`` (the exit status: 0 done and every plan found, 1 some plan failed,
2 bad input); the first line of its docstring is the target's help and its first
paragraph the description. Adding a
benchmark is one line here.
"""

import importlib

#: Benchmark targets: name -> module with ``add_arguments`` and ``run``.
TARGETS = {
    'paper': 'fusion_planner.bench.paper',
    'movingai': 'fusion_planner.bench.movingai',
    'peers': 'fusion_planner.bench.peers',
    'local': 'fusion_planner.bench.local',
    'refine': 'fusion_planner.bench.refine',
    'families': 'fusion_planner.bench.families',
}


def add_parser(subparsers):
    """Register the ``bench`` sub-command and one sub-parser per target."""
    parser = subparsers.add_parser(
        'bench', help='run a benchmark',
        description='Run a benchmark and print its table (or JSON). Exit status: 0 done, '
                    '1 a plan failed, 2 bad input.')
    targets = parser.add_subparsers(dest='target', metavar='TARGET', required=True)
    for name, module_name in TARGETS.items():
        module = importlib.import_module(module_name)
        doc = (module.__doc__ or name).strip()
        first_paragraph = ' '.join(doc.split('\n\n')[0].split())
        target = targets.add_parser(name, help=doc.splitlines()[0], description=first_paragraph)
        module.add_arguments(target)
        target.set_defaults(func=module.run)
    return parser


def run(args):
    """Run the chosen target (dispatched through ``args.func``)."""
    return args.func(args)
