"""The import circles of a graph of modules or files (Tarjan's strongly connected
components), shared by the Python and the Rust layout tests."""

from __future__ import annotations

from collections.abc import Iterable, Mapping


def import_circles(graph: Mapping[str, Iterable[str]]) -> list[list[str]]:
    """Every strongly connected component of ``graph`` (node → the nodes it imports)
    with more than one node, each sorted, in the order Tarjan's walk closes them."""
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    stack: list[str] = []
    circles: list[list[str]] = []

    def visit(node: str) -> None:
        index[node] = low[node] = len(index)
        stack.append(node)
        for nxt in graph[node]:
            if nxt not in index:
                visit(nxt)
                low[node] = min(low[node], low[nxt])
            elif nxt in stack:
                low[node] = min(low[node], index[nxt])
        if low[node] == index[node]:
            component = []
            while True:
                member = stack.pop()
                component.append(member)
                if member == node:
                    break
            if len(component) > 1:
                circles.append(sorted(component))

    for node in graph:
        if node not in index:
            visit(node)
    return circles
