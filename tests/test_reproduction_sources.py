"""Every reproduction cites its paper (not a file outside the repository), and the outputs
committed under ``docs/reproductions/`` carry the same citation as the code that wrote them."""

import importlib
import json
from pathlib import Path

import pytest

from experiments.reproductions import REPRODUCTIONS

DOCS = Path(__file__).resolve().parents[1] / "docs" / "reproductions"
AUTHORS = {
    "feedback-linearization": "Modares Mechanical Engineering",
    "q-learning-lqr": "Taji Heravi, F. and Basohbat Novinzadeh, A. (2017)",
    "fault-tolerant-smc": "Sadigh, S. M., Kashaninia, A. and Dehghan, S. M. M. (2022)",
    "ga-pid": "Ahangarani Farahani, A., Adami, A. and Arefkhani, H.",
    "fuel-slosh": "Navabi, M. and Davoodi, A.",
}


def test_every_reproduction_is_listed_here():
    assert set(REPRODUCTIONS) == set(AUTHORS)


@pytest.mark.parametrize("paper", sorted(AUTHORS))
def test_the_source_is_the_papers_citation_in_code_and_in_the_committed_outputs(paper):
    source = importlib.import_module(REPRODUCTIONS[paper].split(":")[0]).SOURCE
    assert AUTHORS[paper] in source and ".txt" not in source
    doc = json.loads((DOCS / paper / f"{paper}.json").read_text(encoding="utf-8"))
    assert doc["source"] == source and "seed_file" not in doc
    md = (DOCS / paper / f"{paper}.md").read_text(encoding="utf-8").splitlines()
    assert md[2] == f"Source: {source}"
