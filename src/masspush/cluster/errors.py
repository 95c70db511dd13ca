"""What goes wrong with a cluster, said in one line."""

RAY_EXTRA = "pip install 'masspush[ray]'"
"""How to get Ray, for the messages that need it."""


class ClusterError(ConnectionError):
    """The cluster cannot be reached, lacks what a task asks for, or lost a task for good."""
