"""
Other nodes with a node's fully qualified name on its ROS graph.

Two nodes of one name on one domain interleave one stream and answer each other's parameter
requests; DDS lets them. The node looks for them now and then, and says so.
"""
from __future__ import annotations


def count_namesakes(node) -> int:
    """Return how many other nodes on ``node``'s graph have its name and namespace."""
    me = (node.get_name(), node.get_namespace())
    return max(0, sum(1 for named in node.get_node_names_and_namespaces() if named == me) - 1)


def namesakes_warning(count: int, name: str) -> str:
    """Return the warning for ``count`` other nodes named ``name`` (fully qualified)."""
    return (f'{count} other node{"s" if count > 1 else ""} named {name} on this domain: their '
            'topics, parameters and services mix with these (give each node its own name or '
            'namespace)')
