"""The JSON Schema of every outbound document (plan, not_observable, withdrawal).

The schema ships in the package (``data/plan-document.schema.json``);
``docs/design/plan-format.md`` explains it field by field.
"""

from __future__ import annotations

import functools
import json
from importlib import resources
from typing import Any, Mapping

__all__ = ["document_schema", "validate_document"]

SCHEMA_FILE = "data/plan-document.schema.json"


@functools.lru_cache(maxsize=1)
def _schema_text() -> str:
    return resources.files("mushrooms.scheduler_core").joinpath(SCHEMA_FILE).read_text()


def document_schema() -> dict[str, Any]:
    """The JSON Schema (draft 2020-12) of outbound documents, as a dict."""
    return json.loads(_schema_text())


def validate_document(doc: Mapping[str, Any]) -> None:
    """Raise ``jsonschema.ValidationError`` unless ``doc`` follows the schema.

    Needs the ``jsonschema`` package (in the ``test`` extra).
    """
    import jsonschema

    schema = document_schema()
    kind = doc.get("type") if isinstance(doc, Mapping) else None
    if kind in schema["$defs"] and kind in ("plan", "not_observable", "withdrawal"):
        # validate against the one definition of this type: clearer errors than oneOf
        schema = dict(schema, oneOf=[{"$ref": f"#/$defs/{kind}"}])
    jsonschema.validate(doc, schema, cls=jsonschema.Draft202012Validator)
