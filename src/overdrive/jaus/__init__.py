from overdrive.jaus import messages  # noqa
