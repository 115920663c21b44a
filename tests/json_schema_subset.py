"""A small validator for the subset of JSON Schema (draft 2020-12) that
docs/result.schema.json uses.

``jsonschema`` is not a dependency of the suite, so the docs test validates with this.
Supported keywords: ``type``, ``required``, ``properties``, ``additionalProperties`` (a
schema), ``items`` (a schema), ``minItems``, ``maxItems``, ``enum``, ``allOf``, ``anyOf``,
``if``/``then``, ``$ref`` (local ``#/$defs/NAME`` only), and the annotations ``$schema``,
``$defs``, ``title``, ``description``. Any other keyword is refused (:class:`SchemaError`),
so that a schema never relies on a keyword this validator would silently ignore.
"""

from __future__ import annotations

ANNOTATIONS = {"$schema", "$defs", "title", "description"}
KEYWORDS = {"type", "required", "properties", "additionalProperties", "items", "minItems",
            "maxItems", "enum", "allOf", "anyOf", "if", "then", "$ref"}


class SchemaError(ValueError):
    """The schema uses a keyword or form outside the supported subset."""


def _is_type(value, name):
    if name == "null":
        return value is None
    if name == "boolean":
        return isinstance(value, bool)
    if name == "integer":
        return (isinstance(value, int) and not isinstance(value, bool)) or (
            isinstance(value, float) and value.is_integer())
    if name == "number":
        return isinstance(value, (int, float)) and not isinstance(value, bool)
    if name == "string":
        return isinstance(value, str)
    if name == "array":
        return isinstance(value, list)
    if name == "object":
        return isinstance(value, dict)
    raise SchemaError(f"unknown type {name!r}")


def _resolve(root, ref):
    if not ref.startswith("#/$defs/"):
        raise SchemaError(f"$ref {ref!r}: only local '#/$defs/NAME' references are supported")
    name = ref[len("#/$defs/"):]
    if name not in root.get("$defs", {}):
        raise SchemaError(f"$ref {ref!r}: no such definition")
    return root["$defs"][name]


def errors(instance, schema, root=None, path="$"):
    """Messages (``path: problem``) for every way ``instance`` fails ``schema``."""
    root = schema if root is None else root
    unknown = set(schema) - KEYWORDS - ANNOTATIONS
    if unknown:
        raise SchemaError(f"unsupported keyword(s) {sorted(unknown)} at {path}")
    found = []
    if "$ref" in schema:
        found += errors(instance, _resolve(root, schema["$ref"]), root, path)
    if "type" in schema:
        names = schema["type"] if isinstance(schema["type"], list) else [schema["type"]]
        if not any(_is_type(instance, name) for name in names):
            found.append(f"{path}: {type(instance).__name__} {instance!r:.60}; "
                         f"expected type {' or '.join(names)}")
            return found
    if "enum" in schema and instance not in schema["enum"]:
        found.append(f"{path}: {instance!r:.60}; expected one of {schema['enum']}")
    if isinstance(instance, dict):
        for key in schema.get("required", []):
            if key not in instance:
                found.append(f"{path}: missing key {key!r}")
        properties = schema.get("properties", {})
        for key, value in instance.items():
            if key in properties:
                found += errors(value, properties[key], root, f"{path}.{key}")
            elif "additionalProperties" in schema:
                found += errors(value, schema["additionalProperties"], root, f"{path}.{key}")
    if isinstance(instance, list):
        if "minItems" in schema and len(instance) < schema["minItems"]:
            found.append(f"{path}: {len(instance)} items; expected at least "
                         f"{schema['minItems']}")
        if "maxItems" in schema and len(instance) > schema["maxItems"]:
            found.append(f"{path}: {len(instance)} items; expected at most "
                         f"{schema['maxItems']}")
        if "items" in schema:
            for i, value in enumerate(instance):
                found += errors(value, schema["items"], root, f"{path}[{i}]")
    for sub in schema.get("allOf", []):
        found += errors(instance, sub, root, path)
    if "anyOf" in schema:
        tried = [errors(instance, sub, root, path) for sub in schema["anyOf"]]
        if all(tried):
            found.append(f"{path}: matches none of anyOf: "
                         + " | ".join("; ".join(t[:2]) for t in tried))
    if "if" in schema and not errors(instance, schema["if"], root, path):
        found += errors(instance, schema.get("then", {}), root, path)
    return found


def validate(instance, schema):
    """Raise ``ValueError`` listing the problems when ``instance`` does not match."""
    problems = errors(instance, schema)
    if problems:
        raise ValueError("; ".join(problems[:10]))
