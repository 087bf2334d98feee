"""Reading URDF XML as ROS tools do, safely.

urdfdom (behind pinocchio, KDL, MoveIt and TRAC-IK) parses URDF with TinyXML, which is more
forgiving than an XML parser: it ends a comment at the first ``-->`` whatever the comment holds
(``--``, an inner ``<!--``, a closing ``--->``) and is not namespace-aware (``<sensor:camera>``
inside a ``<gazebo>`` block needs no ``xmlns:sensor`` declaration). Vendors' files rely on
both. `read_urdf_xml` accepts them with a documented pre-pass and lxml:

1. **Size**: texts and files larger than `MAX_URDF_BYTES` are rejected before reading.
2. **Text**: files are decoded as UTF-8 (a byte-order mark is allowed); a text that cannot be
   encoded as UTF-8 (lone surrogates) is rejected.
3. **Comments** are removed TinyXML's way: from ``<!--`` to the first ``-->`` after it
   (``<![CDATA[...]]>`` sections are kept as they are). A comment without ``-->`` is an error.
   Each removed comment leaves its line breaks, so line numbers in messages stay right.
4. **No DTD**: any ``<!DOCTYPE`` or ``<!ENTITY`` left after step 3 is rejected, so no entity is
   ever defined or expanded (URDF never needs a DTD).
5. **Parse** with lxml's recovering parser with entity resolution, DTD loading and network
   access off and libxml2's default size limits (``huge_tree=False``). Its error log is then
   checked: an undeclared namespace prefix is accepted (the element keeps the name
   ``prefix:tag``), and so is content after ``</robot>`` (text, a second root, the stray
   ``</transmission> -->`` left by a vendor's commented-out block): TinyXML stops reading there
   and urdfdom takes the first ``<robot>``, so optik does the same and warns
   (`UrdfTrailingContentWarning`, with the line where the ignored content starts). Every other
   error (an unclosed or mismatched tag, a bad attribute, an undefined entity ...) is rejected,
   so "recovering" never means silently dropping part of a robot.
6. Elements of a default namespace (``<robot xmlns="...">``) get their local names, as
   TinyXML sees them.

Steps 3 and 5 are what make vendors' files load; steps 1, 2 and 4 keep the reader safe (no
entity expansion, no external resource, bounded memory).

Every rejection is a `ModelError` (or an `InvalidArgumentError` naming ``source`` when the
input is neither a file nor URDF text) whose message names the file (or ``<string>``).
"""

from __future__ import annotations

import codecs
import os
import re
import warnings
from dataclasses import dataclass
from pathlib import Path

from lxml import etree

from optik.errors import InvalidArgumentError, ModelError

__all__ = ["MAX_URDF_BYTES", "UrdfTrailingContentWarning", "UrdfXml", "read_urdf_xml"]

MAX_URDF_BYTES = 32 * 1024 * 1024
"""Largest URDF accepted (bytes of UTF-8). Real robots take well under 1 MB (the largest file
of example-robot-data, TIAGo dual, takes 205 kB); meshes are separate files."""

_DTD = re.compile(r"<!\s*(DOCTYPE|ENTITY)", re.IGNORECASE)
_XML_DECLARATION = re.compile(r"^\s*<\?xml\b.*?\?>", re.DOTALL)
_COMMENT_OR_CDATA = re.compile(r"<!--|<!\[CDATA\[")
_ALLOWED_ERRORS = frozenset({"NS_ERR_UNDEFINED_NAMESPACE"})
"""libxml2 errors that TinyXML would not see: undeclared namespace prefixes."""
_TRAILING = "ERR_DOCUMENT_END"
"""libxml2's "Extra content at the end of the document": what follows the root element."""


class UrdfTrailingContentWarning(UserWarning):
    """A URDF has content after its ``</robot>``; it is ignored, as urdfdom ignores it."""


@dataclass(frozen=True)
class UrdfXml:
    """A parsed URDF document.

    Attributes:
        root: the ``<robot>`` element (lxml).
        label: the file path or ``<string>``, for messages.
        folder: the folder of the file (None for a string), for relative mesh paths.
    """

    root: etree._Element
    label: str
    folder: Path | None


def _text(source: str | os.PathLike[str]) -> tuple[str, str, Path | None]:
    """``(text, label, folder)``: ``source`` is URDF text when it is a string containing ``<``."""
    if isinstance(source, str) and "<" in source:
        if len(source) > MAX_URDF_BYTES:
            raise ModelError(f"<string>: URDF text of {len(source)} characters > {MAX_URDF_BYTES} bytes")
        return source, "<string>", None
    if not isinstance(source, (str, os.PathLike)):
        got = type(source).__name__
        raise InvalidArgumentError("source", f"expected a URDF path or XML string, got {got}")
    path = Path(source)
    if not path.is_file():
        raise InvalidArgumentError("source", f"no URDF file {str(path)!r}")
    try:
        size = path.stat().st_size
        if size > MAX_URDF_BYTES:
            raise ModelError(f"{path}: URDF file of {size} bytes > {MAX_URDF_BYTES} bytes")
        # a leading byte-order mark dropped, as the codec "utf-8-sig" does (whose module import
        # costs a first from_urdf 0.2 ms)
        text = path.read_bytes().removeprefix(codecs.BOM_UTF8).decode("utf-8")
        return text, str(path), path.resolve().parent
    except (OSError, UnicodeDecodeError) as exc:
        raise InvalidArgumentError("source", f"cannot read URDF file {str(path)!r}: {exc}") from exc


def strip_comments(text: str, label: str = "<string>") -> str:
    """``text`` without its comments, TinyXML's way: each ``<!--`` ends at the first ``-->``.

    CDATA sections are copied unchanged; each comment is replaced by its line breaks.

    Raises:
        ModelError: a comment or CDATA section is not terminated (the message gives its line).
    """
    out: list[str] = []
    pos = 0
    while (found := _COMMENT_OR_CDATA.search(text, pos)) is not None:
        start = found.start()
        comment = found.group() == "<!--"
        closing = "-->" if comment else "]]>"
        end = text.find(closing, found.end())
        if end < 0:
            line = text.count("\n", 0, start) + 1
            what = "comment <!--" if comment else "CDATA section"
            raise ModelError(f"{label}: line {line}: {what} is not terminated")
        end += len(closing)
        out.append(text[pos:start])
        out.append("\n" * text.count("\n", start, end) if comment else text[start:end])
        pos = end
    out.append(text[pos:])
    return "".join(out)


def _local_names(root: etree._Element) -> None:
    """Elements of a default namespace get their local name (TinyXML is not namespace-aware);
    prefixed elements (``<xacro:property>``) keep their qualified name, so never match a URDF tag."""
    for el in root.iter():
        if isinstance(el.tag, str) and el.tag.startswith("{") and el.prefix is None:
            el.tag = etree.QName(el).localname


def read_urdf_xml(source: str | os.PathLike[str]) -> UrdfXml:
    """Read and parse URDF text or a URDF file (see the module docstring for every step).

    Raises:
        InvalidArgumentError: ``source`` is neither an existing file nor XML text, the file is
            unreadable or not UTF-8, or the text holds lone surrogates.
        ModelError: too large, an unterminated comment, a DOCTYPE/ENTITY declaration, malformed
            XML, or a root element other than ``<robot>``.

    Warns:
        UrdfTrailingContentWarning: content after ``</robot>`` was ignored.
    """
    text, label, folder = _text(source)
    text = _XML_DECLARATION.sub("", strip_comments(text, label), count=1)
    dtd = _DTD.search(text)
    if dtd:
        raise ModelError(
            f"{label}: URDF contains a <!{dtd.group(1).upper()} declaration; DTDs and entities are "
            "rejected (no entity expansion)"
        )
    try:
        data = text.encode("utf-8")
    except UnicodeEncodeError as exc:
        raise InvalidArgumentError(
            "source", f"{label}: not valid Unicode text ({exc.reason} at character {exc.start})"
        ) from None
    if len(data) > MAX_URDF_BYTES:
        raise ModelError(f"{label}: URDF text of {len(data)} bytes > {MAX_URDF_BYTES} bytes")
    parser = etree.XMLParser(
        recover=True,
        resolve_entities=False,
        load_dtd=False,
        no_network=True,
        huge_tree=False,
        remove_pis=True,
        remove_comments=True,
    )
    try:
        root = etree.fromstring(data, parser)
    except etree.XMLSyntaxError as exc:  # pragma: no cover - recover=True reports in the log
        raise ModelError(f"{label}: malformed XML: {exc}") from None
    errors = [
        e
        for e in parser.error_log
        if e.level >= etree.ErrorLevels.ERROR and e.type_name not in _ALLOWED_ERRORS
    ]
    trailing = [e for e in errors if e.type_name == _TRAILING]
    if trailing and root is not None and len(trailing) == len(errors):
        warnings.warn(
            f"{label}: line {trailing[0].line}: content after </robot> is ignored (as urdfdom ignores it)",
            UrdfTrailingContentWarning,
            stacklevel=4,
        )
        errors = []
    if errors or root is None:
        first = errors[0] if errors else None
        where = f"line {first.line}: {first.message.strip()}" if first else "no root element"
        more = f" (and {len(errors) - 1} more errors)" if len(errors) > 1 else ""
        raise ModelError(f"{label}: malformed XML: {where}{more}")
    _local_names(root)
    if root.tag != "robot":
        raise ModelError(f"{label}: root element is <{root.tag}>, expected <robot>")
    return UrdfXml(root, label, folder)
