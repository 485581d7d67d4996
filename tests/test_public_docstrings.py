"""Every public function, method and property a user reaches from ``import thrustwalk_cli as
tw`` has a docstring (``help(result)`` and an editor's hover are how a notebook user learns the
API): the public names, every class their type hints lead to (fields, properties, method and
function returns, followed to the end) and the objects a loaded walker holds. A compiled model
prints as one line."""

from __future__ import annotations

import inspect
import sys
import typing

import thrustwalk_cli as tw

PACKAGE = "thrustwalk_cli"


def _ours(obj) -> bool:
    return (getattr(obj, "__module__", None) or "").startswith(PACKAGE + ".")


def _hints(obj, namespace: dict) -> dict:
    """The type hints of a function or class; one by one where some name does not resolve
    (an annotation under ``TYPE_CHECKING``), skipping only that one."""
    try:
        return typing.get_type_hints(obj)
    except Exception:  # noqa: BLE001 (fall back to the hints that resolve)
        out = {}
        for name, ann in getattr(obj, "__annotations__", {}).items():
            try:
                out[name] = eval(ann, namespace) if isinstance(ann, str) else ann  # noqa: S307
            except Exception:  # noqa: BLE001
                pass
        return out


def _classes_in(hint):
    if inspect.isclass(hint):
        if _ours(hint) and not hint.__name__.startswith("_"):
            yield hint
        return
    for arg in typing.get_args(hint):
        yield from _classes_in(arg)


def _members(cls):
    """``(name, function, docstring)`` of the public methods and properties ``cls`` defines or
    inherits from a thrustwalk class."""
    for name in dir(cls):
        if name.startswith("_"):
            continue
        raw = inspect.getattr_static(cls, name)
        if isinstance(raw, (staticmethod, classmethod)):
            raw = raw.__func__
        if isinstance(raw, property) and raw.fget is not None:
            yield name, raw.fget, raw.__doc__
        elif inspect.isfunction(raw):
            yield name, raw, raw.__doc__


def public_classes(extra=()) -> list[type]:
    """The public classes and every thrustwalk class their type hints lead to."""
    todo = [getattr(tw, n) for n in tw.__all__ if n != "__version__"] + list(extra)
    seen: list[type] = []
    while todo:
        obj = todo.pop()
        if inspect.isclass(obj):
            if obj in seen or not _ours(obj) or obj.__name__.startswith("_"):
                continue
            seen.append(obj)
            ns = vars(sys.modules[obj.__module__])
            for hint in _hints(obj, ns).values():
                todo.extend(_classes_in(hint))
            for _, fn, _ in _members(obj):
                todo.extend(_classes_in(_hints(fn, fn.__globals__).get("return")))
        elif callable(obj) and _ours(obj):
            todo.extend(_classes_in(_hints(obj, obj.__globals__).get("return")))
    return seen


def undocumented(classes) -> list[str]:
    bad = [f"tw.{n}" for n in tw.__all__ if n != "__version__"
           and not (getattr(tw, n).__doc__ or "").strip()]
    for cls in classes:
        if not (cls.__doc__ or "").strip():
            bad.append(f"{cls.__module__}.{cls.__qualname__}")
        for name, fn, doc in _members(cls):
            if _ours(fn) and not (doc or "").strip():
                bad.append(f"{cls.__module__}.{cls.__qualname__}.{name}")
    return sorted(set(bad))


def test_the_walk_reaches_the_result_objects_and_what_they_hold():
    names = {c.__name__ for c in public_classes()}
    # the public result classes, and what their hints lead to: the limit cycles of
    # zd_limit_cycles, a walker's model and zero dynamics, the impact of a model, energies
    assert {"ControlResult", "RobustnessResult", "RoughGroundResult", "LimitCycles",
            "CompiledModel", "ZeroDynamics", "ImpactResult", "OrbitEnergy", "Multiplier",
            "ThrustModel", "Table"} <= names, sorted(names)
    assert len(names) >= 80


def test_every_public_function_method_and_property_has_a_docstring(walker3):
    held = [type(v) for obj in (walker3, walker3.model, walker3.zd) for v in vars(obj).values()
            if _ours(type(v))]  # e.g. the model's tape: an attribute without a hint
    bad = undocumented(public_classes(held))
    # the model's generated functions (model.D, model.C, ...) are attributes of the instance
    bad += [f"CompiledModel.{n}" for n, v in vars(walker3.model).items()
            if not n.startswith("_") and callable(v) and not inspect.isclass(v)
            and not (v.__doc__ or "").strip()]
    assert not bad, "no docstring (say what it returns, units, SPEC section):\n" + \
        "\n".join(bad)


def test_a_compiled_model_prints_as_one_line(walker3):
    model = walker3.model
    text = repr(model)
    robot = walker3.robot
    assert "\n" not in text and "object at 0x" not in text
    assert text == (f"CompiledModel(robot={robot.name!r}, links={len(robot.links)}, "
                    f"thrusters={[t.name for t in robot.thrusters]!r}, "
                    f"cache={model.summary()['cache_entry']!r})")
