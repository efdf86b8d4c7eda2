"""Which sensors are timed against which: the protocol's joints, then anatomical neighbours
(pelvis–thigh, thorax–upper arm, pelvis–lumbar–thorax, …), so that every sensor reaches one
reference sensor (pelvis, else thorax, else the first segment) through a tree
(:func:`sync_tree`). Where no sensor joins two parts of the body (the legs without a pelvis
sensor, the arms without a thorax sensor), each part is a tree of its own with its own root
(:func:`sync_forest`): nothing anatomical ties their clocks."""

from __future__ import annotations

from collections import deque

from motionlab.binding import sensor_for_segment
from motionlab.clocksync.common import MIN_SAMPLES, finite_samples
from motionlab.kinematics.segment_types import kind_side
from motionlab.protocol import Protocol
from motionlab.session import Session

# Anatomical neighbours by segment kind (a joint centre between them), proximal first.
NEIGHBOURS = (
    ("pelvis", "thigh"),
    ("thigh", "shank"),
    ("shank", "foot"),
    ("pelvis", "lumbar"),
    ("lumbar", "thorax"),
    ("pelvis", "thorax"),
    ("thorax", "upperarm"),
    ("upperarm", "forearm"),
    ("forearm", "hand"),
    ("thorax", "head"),
)
ROOTS = ("pelvis", "thorax")


def joint_pairs(session: Session, protocol: Protocol) -> list[tuple[str, str]]:
    """(proximal, distal) segment pairs with usable sensors that share a joint centre: the
    protocol's joints, then anatomical neighbours."""
    present = [s for s in protocol.segments if _usable(session, s)]
    edges = [(j.proximal, j.distal) for j in protocol.joints.values()]
    for p in present:
        for d in present:
            if _neighbours(p, d) and (p, d) not in edges:
                edges.append((p, d))
    return [(p, d) for p, d in edges if p in present and d in present]


def sync_tree(session: Session, protocol: Protocol) -> list[tuple[str, str]]:
    """(reference segment, segment) pairs in breadth-first order from the root segment (the
    first tree of :func:`sync_forest`)."""
    forest = sync_forest(session, protocol)
    return forest[0][1] if forest else []


def sync_forest(session: Session, protocol: Protocol) -> list[tuple[str, list[tuple[str, str]]]]:
    """``[(root segment, (reference segment, segment) pairs in breadth-first order)]``: the
    tree of the root segment (pelvis, else thorax, else the first segment), then one tree for
    each part of the body its joints do not reach, rooted at that part's first segment in the
    protocol's order (a part of one segment has no pairs)."""
    present = [s for s in protocol.segments if _usable(session, s)]
    edges = joint_pairs(session, protocol)
    first = next((s for r in ROOTS for s in present if s == r), present[0] if present else None)
    forest, seen = [], set()
    for root in [first, *present] if first is not None else []:
        if root in seen:
            continue
        order, todo = [], deque([root])
        seen.add(root)
        while todo:
            node = todo.popleft()
            for p, d in edges:
                other = d if p == node else p if d == node else None
                if other is not None and other not in seen:
                    seen.add(other)
                    order.append((node, other))
                    todo.append(other)
        forest.append((root, order))
    return forest


def _usable(session: Session, segment: str) -> bool:
    label = sensor_for_segment(session, segment)
    return label is not None and finite_samples(session.sensors[label]) >= MIN_SAMPLES


def _neighbours(a: str, b: str) -> bool:
    (ka, sa), (kb, sb) = kind_side(a), kind_side(b)
    return (ka, kb) in NEIGHBOURS and (not sa or not sb or sa == sb)
