"""Shared fixtures: the case files and small helpers to shorten or modify cases."""

from __future__ import annotations

import dataclasses as dc
from pathlib import Path

import pytest

import dttmm

CASES = Path(__file__).resolve().parents[1] / "experiments" / "cases"


def case(name: str) -> dttmm.Case:
    return dttmm.load_case(CASES / f"{name}.toml")


def shortened(c: dttmm.Case, duration: float, output_step: float | None = None) -> dttmm.Case:
    s = c.scenario
    return dc.replace(c, scenario=dc.replace(s, duration=duration, output_step=output_step or s.output_step))


def with_links(c: dttmm.Case, **beam_changes) -> dttmm.Case:
    """Replace beam fields of every link (e.g. EI=...)."""
    links = tuple(
        dc.replace(
            l,
            beam=dc.replace(
                l.beam, **{k: (v(l.beam) if callable(v) else v) for k, v in beam_changes.items()}
            ),
        )
        for l in c.model.links
    )
    return dc.replace(c, model=dc.replace(c.model, links=links))


@pytest.fixture
def single_link():
    return case("single_link")


@pytest.fixture
def three_link():
    return case("three_link")


@pytest.fixture
def spin_up():
    return case("spin_up")
