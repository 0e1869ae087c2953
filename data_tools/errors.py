"""The one error type for bad user input (files, arguments, values)."""


class InputError(ValueError):
    """Bad input from the user: the message is one line, fit to print as is.

    The command line prints it after ``parc: error:`` and exits with status 2,
    without a traceback.
    """
