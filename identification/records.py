"""Results as frozen dataclasses whose JSON is the records the commands write.

A :class:`Record` is a frozen dataclass whose field names are the keys of its JSON object, in
the order the file has them: ``to_json()`` gives the object (``json.dumps(..., indent=2)`` of it
is the file's text), ``from_json(d)`` reads it back.  Nested records are written as objects and
tuples as lists.  The validation's sections (:mod:`identification.validation`), the
reproduction's (:mod:`omni_studies.reproduce`), the Z-width's map (``zwidth.json``,
:mod:`omni_studies.zwidth`) and a sweep variant's result (``result.json``,
:mod:`omni_studies.sweep`) are records.
"""

from __future__ import annotations

from dataclasses import fields


class Record:
    """A frozen dataclass whose field names are the keys of its JSON object, in order."""

    def to_json(self) -> dict:
        """The JSON object (plain dicts, lists, numbers and strings), keys in field order."""
        return {f.name: json_value(getattr(self, f.name)) for f in fields(self)}

    @classmethod
    def from_json(cls, d: dict):
        """The record of the JSON object ``d`` (the keys must be exactly the fields)."""
        return cls(**d)


def json_value(value):
    """``value`` as JSON: records as objects, tuples as lists, the rest as it is."""
    if isinstance(value, Record):
        return value.to_json()
    if isinstance(value, tuple):
        return [json_value(v) for v in value]
    return value
