#!/usr/bin/python3
"""Independent check of schemas/campaign.schema.json with Debian's python3-jsonschema.

Usage: check_campaign_schema.py SOURCE_DIR

- The schema itself is valid JSON Schema 2020-12.
- Every campaigns/*.json validates against it.
- The bad-campaign corpus (tests/tasks/bad_campaigns, classified in its expected.json) agrees:
  "syntax" files are not JSON, "schema" files are rejected by the schema, and "semantic" files
  (cross-field and sweep mistakes that JSON Schema cannot express) are accepted by it, so the
  schema is never stricter than millflow itself.
Exits 1 with one line per disagreement.
"""
import json
import pathlib
import sys

from jsonschema import Draft202012Validator


def load(path):
    with open(path, encoding="utf-8") as stream:
        return json.load(stream)


def schema_errors(validator, document):
    return [f"{'/' + '/'.join(map(str, e.absolute_path))}: {e.message}" for e in validator.iter_errors(document)]


def check_campaigns(validator, source):
    problems = []
    campaigns = sorted((source / "campaigns").glob("*.json"))
    if not campaigns:
        problems.append("no campaigns/*.json found")
    for path in campaigns:
        for error in schema_errors(validator, load(path)):
            problems.append(f"{path.name}: rejected by the schema: {error}")
    return problems


def check_corpus_file(validator, path, level):
    try:
        document = load(path)
    except json.JSONDecodeError:
        return [] if level == "syntax" else [f"{path.name}: not JSON, but classified {level}"]
    if level == "syntax":
        return [f"{path.name}: parses as JSON, but classified syntax"]
    errors = schema_errors(validator, document)
    if level == "schema" and not errors:
        return [f"{path.name}: accepted by the schema, but classified schema"]
    if level == "semantic" and errors:
        return [f"{path.name}: classified semantic, but the schema rejects it: {errors[0]}"]
    return []


def check_corpus(validator, source):
    corpus = source / "tests" / "tasks" / "bad_campaigns"
    expected = load(corpus / "expected.json")
    problems = []
    for name, entry in sorted(expected.items()):
        problems += check_corpus_file(validator, corpus / name, entry["level"])
    return problems


def main():
    source = pathlib.Path(sys.argv[1])
    schema = load(source / "schemas" / "campaign.schema.json")
    Draft202012Validator.check_schema(schema)
    validator = Draft202012Validator(schema)
    problems = check_campaigns(validator, source) + check_corpus(validator, source)
    for problem in problems:
        print(problem)
    print(f"{len(problems)} disagreement(s) between the schema and millflow's own checks")
    return 1 if problems else 0


if __name__ == "__main__":
    sys.exit(main())
