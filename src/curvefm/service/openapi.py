"""The published OpenAPI schema is the truth: completed with the installed plugins, and checked on every body.

The request models name a plugin with a string and take its parameters as a free object, because plugins are
installed, not declared. Here, once per process, each (plugin name, parameters) pair of a request becomes one
variant per installed plugin: the name a constant, the parameters that plugin's own schema. A request the
schema accepts then names an installed plugin with parameters it takes (a parameter model's checks that relate
two fields, such as ZoomOut's ``k_final >= k_init``, are the one thing a JSON schema cannot say).

JSON bodies are validated against that published schema before pydantic parses them (:class:`SchemaRoute`):
pydantic's lax mode would take ``"2"`` for a number or ``0`` for a boolean, which the schema rejects.
The configured request limits that are known at start (``max_k``, ``max_members``, ...) are the schema's
``maximum`` and ``maxItems`` (marked with :data:`LIMIT_KEY`); a body past one is the schema's 422, whose message and
``limit`` name the setting. And every operation lists the statuses that the layers around the routes answer: 429 (the
rate limit) on all but the unlimited paths, 408 and 413 (the body's timeout and size) on those that take a body.

A body is checked by ``jsonschema_rs`` first (compiled, about 200x faster than ``jsonschema``: the check was 8% of
a curve edit's time under load); only a body it rejects goes to ``jsonschema``, the reference, whose errors
:func:`_explain` turns into the message.
"""

from __future__ import annotations

import copy
import json
from collections.abc import Callable, Coroutine, Mapping
from dataclasses import dataclass
from typing import Any, cast

import jsonschema_rs
from fastapi import FastAPI, Request, Response
from fastapi.exceptions import RequestValidationError
from fastapi.openapi.utils import get_openapi
from fastapi.routing import APIRoute
from jsonschema import Draft202012Validator, ValidationError

from curvefm import registry
from curvefm.errors import LimitExceeded
from curvefm.service.errors import DESCRIPTIONS, BoundExceeded
from curvefm.service.models import ErrorBody
from curvefm.service.settings import Settings, env_name


@dataclass(frozen=True)
class PluginField:
    kind: str
    name: str
    """the field naming the plugin"""
    params: str | None = None
    """the field holding its parameters (``None``: the plugin is named with no parameters)"""


PLUGIN_FIELDS = {
    "BasisRequest": [PluginField("basis", "plugin", "params")],
    "SessionCreate": [PluginField("basis", "basis_plugin", "basis_params"), PluginField("tracer", "tracer")],
    "CurveSpec": [PluginField("tracer", "tracer", "tracer_params")],
    "RefineRequest": [PluginField("converter", "converter", "params")],
    "RunRequest": [PluginField("converter", "converter", "params")],
    "CollectionCreate": [PluginField("basis", "basis_plugin", "basis_params"), PluginField("tracer", "tracer")],
    "TemplateCurveSpec": [PluginField("tracer", "tracer", "tracer_params")],
    "AnswerRequest": [PluginField("tracer", "tracer", "tracer_params")],
}
"""Request schemas (components) -> their plugin fields."""

VERTEX_LISTS = ("max_waypoints", "max_path_vertices")
"""A curve side's list of vertex ids is waypoints or a whole path: the larger limit bounds it in the schema (the
other is checked as the curve is added, 413 naming it)."""
LIMITED_FIELDS: dict[str, dict[str, tuple[str, ...]]] = {
    "BasisRequest": {"k": ("max_k",)},
    "SessionCreate": {"k": ("max_k",)},
    "CollectionCreate": {"k": ("max_k",), "curves": ("max_curves",), "members": ("max_members",)},
    "MembersRequest": {"shapes": ("max_members",)},
    "RunRequest": {"members": ("max_members",)},
    "CurveSpec": {"source": VERTEX_LISTS, "target": VERTEX_LISTS},
    "TemplateCurveSpec": {"waypoints": VERTEX_LISTS},
    "AnswerRequest": {"target": VERTEX_LISTS},
    "NewThread": {"text": ("max_comment_chars",)},
    "CommentReply": {"text": ("max_comment_chars",)},
}
"""Request schemas (components) -> their fields bounded by configured limits (settings)."""
LIMIT_KEY = "x-curvefm-limit"
"""Marks a ``maximum`` or ``maxItems`` that is a configured limit: its setting's name."""
BOUNDING_KEYWORDS = {"integer": "maximum", "array": "maxItems", "string": "maxLength"}
BODY_STATUSES = (408, 413)
"""What the body's read (:class:`curvefm.service.app.BodySizeLimit`) answers on every operation with a body."""

NO_PARAMETERS = {"type": "object", "maxProperties": 0, "description": "no parameters without a plugin named"}


def install_openapi(app: FastAPI, settings: Settings, rate_limited: Callable[[str], bool]) -> None:
    """Make ``app.openapi()`` (``/openapi.json``, ``/docs``) publish the installed plugins' names and parameters,
    the configured limits of ``settings``, and 429 on the paths that are ``rate_limited``."""

    def openapi() -> dict:
        if app.openapi_schema is None:
            schema = get_openapi(title=app.title, version=app.version, description=app.description, routes=app.routes)
            with_limits(schema, settings)
            with_plugins(schema)
            with_statuses(schema, rate_limited)
            app.openapi_schema = schema
        return app.openapi_schema

    app.openapi = openapi  # type: ignore[method-assign]  # FastAPI's documented way to extend the schema
    app.state.body_validators = {}


def with_plugins(schema: dict) -> dict:
    components = schema["components"]["schemas"]
    for name, plugin_fields in PLUGIN_FIELDS.items():
        if name in components:
            components[name] = plugin_variants(components[name], plugin_fields, components)
    return schema


def with_limits(schema: dict, settings: Settings) -> None:
    """The configured limits of :data:`LIMITED_FIELDS` as the fields' bounds (before the plugin variants copy
    the fields)."""
    components = schema["components"]["schemas"]
    for model, fields in LIMITED_FIELDS.items():
        for field, names in fields.items():
            name = max(names, key=lambda n: getattr(settings, n))
            _bound(components[model]["properties"][field], name, getattr(settings, name))


def _bound(field: dict, setting: str, limit: int) -> None:
    for branch in field.get("anyOf", [field]):
        keyword = BOUNDING_KEYWORDS.get(branch.get("type", ""))
        if keyword:
            branch[keyword] = limit
            branch[LIMIT_KEY] = setting
    field["description"] = f"{field.get('description', '')} (at most {limit}: {env_name(setting)})".lstrip()


def with_statuses(schema: dict, rate_limited: Callable[[str], bool]) -> None:
    """429 on every rate-limited operation, 408 and 413 on every operation with a body."""
    for path, operations in schema["paths"].items():
        for operation in operations.values():
            statuses = [429] if rate_limited(path) else []
            statuses += BODY_STATUSES if "requestBody" in operation else []
            for status in statuses:
                operation["responses"].setdefault(str(status), _error_answer(status))


def _error_answer(status: int) -> dict:
    schema = {"$ref": f"#/components/schemas/{ErrorBody.__name__}"}
    return {"description": DESCRIPTIONS[status], "content": {"application/json": {"schema": schema}}}


def plugin_variants(model: dict, plugin_fields: list[PluginField], components: dict) -> dict:
    """``model`` as one variant per combination of installed plugins (a plugin field without parameters
    becomes an enum instead)."""
    variants = [model]
    for field in plugin_fields:
        if field.params is None:
            for variant in variants:
                _name_property(variant, field, enum=registry.names(field.kind))
        else:
            variants = [split for variant in variants for split in _split(variant, field, components)]
    if len(variants) == 1:
        return variants[0]
    common = {key: model[key] for key in ("title", "description") if key in model}
    return {**common, "anyOf": variants}


def _split(model: dict, field: PluginField, components: dict) -> list[dict]:
    default = model["properties"][field.name].get("default")
    variants = []
    for plugin_name in registry.names(field.kind):
        variant = copy.deepcopy(model)
        _name_property(variant, field, enum=[plugin_name])
        variant["properties"][field.params] = _params_schema(registry.get(field.kind, plugin_name), components)
        if plugin_name != default:
            variant["required"] = sorted({*variant.get("required", ()), field.name})
        variants.append(variant)
    if default is None:  # the name may be null or absent: then no parameters either
        variant = copy.deepcopy(model)
        _name_property(variant, field, enum=[None])
        variant["properties"][field.params] = NO_PARAMETERS
        variants.append(variant)
    return variants


def _name_property(model: dict, field: PluginField, enum: list) -> None:
    current = model["properties"][field.name]
    keep = {key: current[key] for key in ("title", "description", "default") if key in current}
    model["properties"][field.name] = {**keep, "enum": enum}


def _params_schema(plugin: registry.Plugin, components: dict) -> dict:
    """The plugin's parameter schema, its ``$defs`` moved into the components (named after the plugin, so two
    plugins' models of the same name stay apart)."""
    params = plugin.Params.model_json_schema(ref_template=f"#/components/schemas/{plugin.name}.{{model}}")
    for model_name, definition in params.pop("$defs", {}).items():
        components[f"{plugin.name}.{model_name}"] = definition
    return params


class SchemaRoute(APIRoute):
    """A route whose JSON body must match the published schema of its operation (422 naming the first
    problem otherwise); the body is then parsed by its pydantic model as usual."""

    def get_route_handler(self) -> Callable[[Request], Coroutine[Any, Any, Response]]:
        handler = super().get_route_handler()

        async def validated(request: Request) -> Response:
            if request.headers.get("content-type", "").startswith("application/json"):
                validator = body_validator(request.app, self.path_format, request.method)
                if validator is not None:
                    validator.check(await request.body(), request.app.state.services.settings.max_json_depth)
            return await handler(request)

        return validated


@dataclass(frozen=True)
class BodyValidator:
    """One operation's body schema, compiled twice: ``fast`` accepts, ``reference`` explains (module doc)."""

    fast: jsonschema_rs.Draft202012Validator
    reference: Draft202012Validator

    def check(self, body: bytes, max_depth: int) -> None:
        """Raise FastAPI's :class:`RequestValidationError` naming the first problem if ``body`` (JSON) does not
        match the schema, :class:`LimitExceeded` if it nests deeper than ``max_depth``; malformed JSON is left to
        FastAPI."""
        try:
            instance = json.loads(body)
        except RecursionError:
            raise too_deep(max_depth) from None
        except ValueError:
            return
        if nesting_depth(instance) > max_depth:
            raise too_deep(max_depth)
        if self.fast.is_valid(instance):
            return
        errors = list(self.reference.iter_errors(instance))
        bound = next(filter(None, map(_configured_limit, errors)), None)
        if bound is not None:
            raise bound
        error = next(iter(errors), None)
        if error is not None:
            path, message = _explain(error)
            raise RequestValidationError([{"loc": ("body", *path), "msg": message, "type": "schema"}])


def too_deep(max_depth: int) -> LimitExceeded:
    return LimitExceeded("max_json_depth", max_depth, "the JSON body nests arrays and objects", " levels")


def nesting_depth(instance: object) -> int:
    """How deep arrays and objects nest in a parsed JSON value (without recursion: the value may be deep)."""
    deepest, stack = 0, [(instance, 1)]
    while stack:
        value, depth = stack.pop()
        children = value.values() if isinstance(value, dict) else value if isinstance(value, list) else None
        if children is None:
            continue
        deepest = max(deepest, depth)
        stack.extend((child, depth + 1) for child in children if isinstance(child, dict | list))
    return deepest


def body_validator(app: FastAPI, path: str, method: str) -> BodyValidator | None:
    """The validator of an operation's JSON body (``None``: it takes none), compiled on first use."""
    validators = app.state.body_validators
    key = (path, method.lower())
    if key not in validators:
        document = app.openapi()
        operation = document["paths"].get(path, {}).get(key[1], {})
        schema = operation.get("requestBody", {}).get("content", {}).get("application/json", {}).get("schema")
        # the components ride along in the root so that "#/components/..." references resolve
        root = schema and {**schema, "components": document["components"]}
        validators[key] = root and BodyValidator(
            jsonschema_rs.Draft202012Validator(root, validate_formats=False), Draft202012Validator(root)
        )
    return validators[key]


def _configured_limit(error: ValidationError) -> BoundExceeded | None:
    """The configured limit (:data:`LIMIT_KEY`) that ``error`` or one of its variants' errors passes, if any:
    a bounded field is alike in every plugin variant, so passing it in one is passing it."""
    pending = [error]
    while pending:
        current = pending.pop()
        pending += current.context or []
        setting = current.schema.get(LIMIT_KEY) if isinstance(current.schema, Mapping) else None
        if setting and current.validator in BOUNDING_KEYWORDS.values():
            path = list(current.absolute_path)
            what = _what(path, current.instance)
            return BoundExceeded(path, LimitExceeded(setting, cast(int, current.validator_value), what))
    return None


def _what(path: list, value: object) -> str:
    """What passed a bound: a list's length, a text's (not the text itself), a number."""
    if isinstance(value, list):
        return f"{len(value)} items"
    if isinstance(value, str):
        return f"{path[-1]} of {len(value)} characters"
    return f"{path[-1]} = {value}"


def _explain(error: ValidationError) -> tuple[list, str]:
    """Where and what: of an error in an ``anyOf`` (the plugin variants), the problems that got furthest into
    the body; a name no variant has lists every variant's names."""
    while error.context:
        depth = max(len(e.absolute_path) for e in error.context)
        deepest = [e for e in error.context if len(e.absolute_path) == depth]
        if all(e.validator == "enum" for e in deepest):
            allowed = [value for e in deepest for value in cast(list[Any], e.validator_value)]  # enum's values
            return list(deepest[0].absolute_path), f"{deepest[0].instance!r} is not one of {allowed}"
        error = deepest[0]
    path = list(error.absolute_path)
    extra = _extra_fields(error)
    if extra:  # name the field itself, as pydantic would
        return [*path, extra[0]], "extra field not permitted"
    return path, error.message


def _extra_fields(error: ValidationError) -> list[str]:
    if error.validator != "additionalProperties" or not isinstance(error.instance, dict):
        return []
    schema = cast(Mapping[str, Any], error.schema)  # additionalProperties fails in an object's schema
    return sorted(set(error.instance) - set(schema.get("properties", {})))
