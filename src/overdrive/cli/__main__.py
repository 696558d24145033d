"""``python -m overdrive.cli``: the same as the ``overdrive`` command."""

from overdrive.cli.main import main

main()
