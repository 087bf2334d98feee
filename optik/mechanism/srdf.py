"""The ``disable_collisions`` pairs of an SRDF file (MoveIt's semantic robot description).

An SRDF is XML with a ``<robot>`` root; of it optik reads only the elements
``<disable_collisions link1="a" link2="b" reason="..."/>``: the link pairs that need no
collision check (adjacent links, pairs that can never touch, pairs always in contact). The text
is read as a URDF is (`optik.mechanism.urdf_xml.read_urdf_xml`: same size limit, no DTD, no
entity, TinyXML comments). Pairs naming links that are not loaded are kept: they never match.
"""

from __future__ import annotations

import os

from optik.errors import InvalidArgumentError, ModelError
from optik.mechanism.urdf_xml import read_urdf_xml

__all__ = ["read_disabled_collisions"]


def read_disabled_collisions(source: str | os.PathLike[str]) -> frozenset[tuple[str, str]]:
    """The ``disable_collisions`` pairs of an SRDF file or text, each as a sorted name pair.

    Raises:
        InvalidArgumentError: ``source`` is neither a file nor XML text (named ``srdf``).
        ModelError: malformed XML, or a ``<disable_collisions>`` without both links (the message
            names the file).
    """
    try:
        doc = read_urdf_xml(source)
    except InvalidArgumentError as exc:
        raise InvalidArgumentError("srdf", str(exc).removeprefix("source: ")) from None
    pairs: set[tuple[str, str]] = set()
    for i, el in enumerate(doc.root.findall("disable_collisions")):
        a, b = el.get("link1"), el.get("link2")
        if not a or not b:
            raise ModelError(f"{doc.label}: <disable_collisions> {i} needs link1 and link2")
        pairs.add((a, b) if a <= b else (b, a))
    return frozenset(pairs)
