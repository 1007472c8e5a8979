"""Measures read their dependencies through typed readers that refuse a value of the wrong kind."""

from __future__ import annotations

import pytest

from multion.task.measures import EpisodeState, Measure, MetricValue, number, series


class Fixed(Measure):
    name = "fixed"

    def __init__(self, value: MetricValue) -> None:
        self._value = value

    def reset(self, state: EpisodeState, measures: dict[str, Measure]) -> None:
        pass

    def update(self, state: EpisodeState, measures: dict[str, Measure]) -> None:
        pass

    @property
    def value(self) -> MetricValue:
        return self._value


def test_number_reads_ints_and_floats() -> None:
    assert number({"fixed": Fixed(3)}, "fixed") == 3.0
    assert number({"fixed": Fixed(0.25)}, "fixed") == 0.25


def test_series_reads_lists_of_numbers() -> None:
    assert series({"fixed": Fixed([1.0, 2.5])}, "fixed") == [1.0, 2.5]


@pytest.mark.parametrize("value", ["3", None, [1.0]])
def test_number_names_a_measure_that_is_not_a_number(value: MetricValue) -> None:
    with pytest.raises(TypeError, match="measure 'fixed' is .*not a number"):
        number({"fixed": Fixed(value)}, "fixed")


@pytest.mark.parametrize("value", [1.0, "ab", ["a"]])
def test_series_names_a_measure_that_is_not_a_list_of_numbers(value: MetricValue) -> None:
    with pytest.raises(TypeError, match="measure 'fixed' is .*not a list of numbers"):
        series({"fixed": Fixed(value)}, "fixed")
