"""How a run of the ``parafab`` CLI ended (no Qt, no FreeCAD: the run objects, the feature
modules that record a run and the task panels that show it all use it).

``Outcome.state`` is one of SOLVED, ERROR or CANCELLED: a cancelled run is told apart by its
state, never by the words of its message.
"""

SOLVED, ERROR, CANCELLED = "solved", "error", "cancelled"


class Outcome(object):
    """How a run ended: ``state`` is SOLVED, ERROR or CANCELLED; ``result`` the CLI's JSON
    (SOLVED; for an interrupted optimization its history), ``message`` what to tell the user."""

    def __init__(self, state, result=None, message=""):
        self.state = state
        self.result = result
        self.message = message

    @property
    def solved(self):
        return self.state == SOLVED

    @property
    def cancelled(self):
        return self.state == CANCELLED

    def __repr__(self):
        return "Outcome(%r, %r)" % (self.state, self.message)
