"""The one exception type a user can cause.

Every command line entry point catches :class:`UserError`, prints ``error: <message>`` on one
line to stderr and exits with status 2 (see ``omni_sim.cli``).  Library code raises it for bad
input (missing file, malformed data, impossible values); programming errors stay ordinary
exceptions so they keep their traceback.
"""


class UserError(Exception):
    """Bad input from the user: reported as one line, exit status 2."""
