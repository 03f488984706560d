"""proto/scene.schema.json and the C++ scene parser agree.

Every scene the tests use must validate; every bad-input case in tests/scenes/invalid (which
proto/scene/scene_test.cpp feeds to the parser) must be refused by the schema too, except
the cases marked "parser_only": rules JSON Schema cannot express, which the schema must
then accept, so that the list of them stays exactly the gap.
"""
import ast
import json
import pathlib
import re

import jsonschema
import pytest

ROOT = pathlib.Path(__file__).resolve().parent.parent.parent
SCENES = ROOT / "tests" / "scenes"
SCHEMA = json.loads((ROOT / "proto" / "scene.schema.json").read_text())
VALIDATOR = jsonschema.Draft202012Validator(SCHEMA)


def load_cases():
    cases = []
    for path in sorted((SCENES / "invalid").glob("*.json")):
        for case in json.loads(path.read_text())["cases"]:
            cases.append(pytest.param(case, id=f"{path.stem}/{case['name']}"))
    return cases


def scenes_in(value):
    """Every object in `value` that has what a scene must have: a camera and render settings."""
    if isinstance(value, dict):
        if "camera" in value and "render" in value:
            yield value
        for item in value.values():
            yield from scenes_in(item)
    elif isinstance(value, list):
        for item in value:
            yield from scenes_in(item)


def embedded_python_scenes():
    """Scenes written as literal dicts in the Python tests."""
    found = []
    for path in sorted((ROOT / "tests").rglob("*.py")):
        for node in ast.walk(ast.parse(path.read_text())):
            if not isinstance(node, ast.Dict):
                continue
            keys = {key.value for key in node.keys if isinstance(key, ast.Constant)}
            if not {"camera", "render"} <= keys:
                continue
            try:
                scene = ast.literal_eval(node)
            except ValueError:
                continue  # built from variables: not a literal to check here
            found.append(pytest.param(scene, id=f"{path.relative_to(ROOT)}:{node.lineno}"))
    return found


RAW_STRING = re.compile(r'R"\((.*?)\)"', re.S)


def embedded_cpp_scenes():
    """Scenes written as complete raw-string JSON in the C++ tests (concatenated ones are
    not complete JSON and are left to the parser's own tests)."""
    found = []
    sources = [p for folder in ("proto", "worker", "coordinator") for p in (ROOT / folder).rglob("*_test.cpp")]
    for path in sorted(sources):
        text = path.read_text()
        for match in RAW_STRING.finditer(text):
            try:
                document = json.loads(match.group(1))
            except ValueError:
                continue
            line = text.count("\n", 0, match.start()) + 1
            for scene in scenes_in(document):
                found.append(pytest.param(scene, id=f"{path.relative_to(ROOT)}:{line}"))
    return found


def example_scenes():
    paths = sorted(SCENES.glob("*.json")) + sorted((SCENES / "valid").glob("*.json"))
    return [pytest.param(path, id=str(path.relative_to(SCENES))) for path in paths]


def test_the_schema_is_a_valid_2020_12_schema():
    jsonschema.Draft202012Validator.check_schema(SCHEMA)


@pytest.mark.parametrize("path", example_scenes())
def test_example_and_test_scenes_validate(path):
    VALIDATOR.validate(json.loads(path.read_text()))


@pytest.mark.parametrize("scene", embedded_python_scenes())
def test_scenes_embedded_in_python_tests_validate(scene):
    VALIDATOR.validate(scene)


@pytest.mark.parametrize("scene", embedded_cpp_scenes())
def test_scenes_embedded_in_cpp_tests_validate(scene):
    VALIDATOR.validate(scene)


def test_embedded_scenes_are_found():
    # Guards the collectors above against silently finding nothing.
    assert len(embedded_python_scenes()) >= 2
    assert len(embedded_cpp_scenes()) >= 5


def error_pointers(errors):
    """The JSON pointers of errors, including those inside oneOf/anyOf alternatives."""
    for error in errors:
        yield "".join("/" + str(part).replace("~", "~0").replace("/", "~1") for part in error.absolute_path)
        yield from error_pointers(error.context or [])


@pytest.mark.parametrize("case", load_cases())
def test_bad_input_is_refused_by_schema_as_by_parser(case):
    if "text" in case:
        try:
            # Python reads 1e999 as infinity, which the schema's bounds refuse, and keeps the
            # last of duplicate keys, which only the parser can see.
            document = json.loads(case["text"])
        except ValueError:
            assert "parser_only" not in case
            return  # not JSON at all: nothing to validate, refused before any schema
    else:
        document = case["scene"]
    errors = list(VALIDATOR.iter_errors(document))
    if "parser_only" in case:
        assert not errors, (f"the schema now refuses this case ({errors[0].message}): "
                            "drop its \"parser_only\" mark")
        return
    assert errors, f"the parser refuses at {case['pointer']} but the schema accepts"
    # Some error lies on the way to the value the parser names: at it, or at an object
    # holding it (where JSON Schema reports missing and unknown keys).
    pointer = case["pointer"]
    assert any(pointer == p or pointer.startswith(p + "/") for p in error_pointers(errors)), (
        pointer, sorted(set(error_pointers(errors))))
