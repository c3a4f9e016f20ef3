"""Other nodes of a node's name: counted from the graph, warned once per change (no DDS)."""
from __future__ import annotations

from types import SimpleNamespace

from modal_spring_ros.ros.node import ModalSpringNode
from modal_spring_ros.ros.process.namesakes import count_namesakes, namesakes_warning


class _Graph:
    """A stand-in for a node whose graph is set by the test."""

    def __init__(self, *names):
        self.names = list(names)
        self.warnings = []
        self._namesakes = 0

    def get_name(self):
        return 'modal_spring'

    def get_namespace(self):
        return '/twin'

    def get_fully_qualified_name(self):
        return '/twin/modal_spring'

    def get_node_names_and_namespaces(self):
        return self.names

    def get_logger(self):
        return SimpleNamespace(warning=self.warnings.append)


ME = ('modal_spring', '/twin')


def test_only_nodes_of_the_same_name_and_namespace_count_and_the_node_itself_does_not():
    assert count_namesakes(_Graph(ME)) == 0
    assert count_namesakes(_Graph()) == 0                       # not yet on its own graph
    others = [('modal_spring', '/'), ('modal_spring', '/twin/x'), ('twin', '/modal_spring')]
    assert count_namesakes(_Graph(ME, *others)) == 0
    assert count_namesakes(_Graph(ME, ME, *others, ME)) == 2


def test_the_node_warns_once_per_change_and_is_alone_again_when_the_graph_forgets_the_other():
    graph = _Graph(ME, ME)
    for _ in range(3):
        ModalSpringNode._check_namesakes(graph)
    assert graph.warnings == [namesakes_warning(1, '/twin/modal_spring')]
    assert graph._namesakes == 1 and '1 other node named /twin/modal_spring' in graph.warnings[0]
    graph.names.append(ME)
    ModalSpringNode._check_namesakes(graph)
    assert graph._namesakes == 2 and graph.warnings[-1].startswith('2 other nodes named')
    graph.names = [ME]
    ModalSpringNode._check_namesakes(graph)
    assert graph._namesakes == 0 and len(graph.warnings) == 2   # alone: no warning, count cleared
    graph.names = [ME, ME]
    ModalSpringNode._check_namesakes(graph)
    assert len(graph.warnings) == 3                             # a new namesake is warned again
