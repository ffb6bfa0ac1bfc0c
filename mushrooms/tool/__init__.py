"""The command-line tools, one module each (``mushrooms plan`` is :mod:`mushrooms.tool.plan`).

Every tool module has ``HELP`` (one line), ``parser(p=None)`` (its options,
added to ``p`` or to a new parser), ``run(args)`` (the command, returns the
exit status) and ``main(args=None)`` (the tool on its own:
``python -m mushrooms.tool.plan --help``).  :mod:`mushrooms.cli` is only the
dispatcher.  Tool modules import nothing heavy at module level, so ``--help``
is fast.
"""
