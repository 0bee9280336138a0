"""A comparison's results as labelled arrays: ``results.csv`` and ``summary.csv`` are views of them.

The equal-time comparison (thesis 8.1.1) measures every method at every
budget and seed. Its results are an :class:`xarray.Dataset` with dimensions
``(method, spp, seed)`` and one data variable per metric and time phase
(:func:`results_dataset`); the equal-time protocol's records per
``(method, spp)`` are one with dimensions ``(method, spp)``
(:func:`summary_dataset`). A cell that was not run (path tracing's ladder
rungs are at other spps than the methods' budgets) is ``NaN``. Reports
select by coordinate (``dataset.sel({'method': 'cosamp', 'spp': 40})``: a
dict, as ``method=`` is ``sel``'s own keyword), never by a row's position;
:func:`dataset_csv` writes the CSV files from the Dataset.

Coordinates: ``method`` in order of first appearance (names as written,
variants such as ``'cosamp:gamma=0.5'`` included), ``spp`` and ``seed``
ascending. Each data variable's ``value_type`` attribute says what its values
were in the rows: ``'real'`` (float64), ``'integer'`` (float64 where a cell
is missing, so that it can hold ``NaN``; int64 otherwise), ``'boolean'`` and
``'text'`` (object arrays, ``NaN`` where missing). A row's empty value (``''``
or ``None``: "not applicable", such as path tracing's own equal-time ratio)
is missing, ``NaN``, like a cell that was not run.

Plain NumPy here; xarray is imported when a Dataset is built (it takes as
long to import as the rest of sparselt). Nothing from ``experiments/``.

References
----------
Thesis 8.1.1 (the equal-time comparison). xarray's data model: Hoyer and
Hamman (2017), "xarray: N-D labeled arrays and datasets in Python",
Journal of Open Research Software 5(1).
"""

from __future__ import annotations

import math
import numbers

import numpy as np

from .table import Table

#: The dimensions of a comparison's results (one cell per method, budget and seed).
RESULT_DIMENSIONS = ("method", "spp", "seed")
#: The dimensions of its equal-time summary (one record per method and budget, seeds aggregated).
SUMMARY_DIMENSIONS = ("method", "spp")
#: ``results.csv``'s row order: methods as first seen, then seed, then spp (each ascending).
RESULT_ROW_ORDER = ("method", "seed", "spp")
VALUE_TYPES = ("real", "integer", "boolean", "text")


def _missing(value):
    """Whether a row's value stands for "no value": ``''``, ``None`` or a float NaN."""
    if value is None or (isinstance(value, str) and value == ""):
        return True
    return isinstance(value, float) and math.isnan(value)


def _value_type(values):
    """The :data:`VALUE_TYPES` entry of a column's present values (bool before int: bool is an int in Python)."""
    if all(isinstance(value, (bool, np.bool_)) for value in values):
        return "boolean"
    if all(isinstance(value, numbers.Integral) and not isinstance(value, (bool, np.bool_)) for value in values):
        return "integer"
    if all(isinstance(value, numbers.Real) and not isinstance(value, (bool, np.bool_)) for value in values):
        return "real"
    return "text"


def _coordinate(records, dimension):
    """A dimension's coordinate: text in order of first appearance, numbers ascending."""
    values = list(dict.fromkeys(record[dimension] for record in records))
    if all(isinstance(value, numbers.Real) for value in values):
        return sorted(values)
    return values


def records_dataset(records, dimensions, *, attributes=None):
    """An :class:`xarray.Dataset` from records (dicts), one cell per distinct value of ``dimensions``.

    Parameters
    ----------
    records : sequence of dict
        Each holds every name of ``dimensions``; its other keys become data
        variables, in order of first appearance.
    dimensions : sequence of str
        The keys that label a cell (``('method', 'spp', 'seed')``).
    attributes : dict, optional
        The Dataset's ``attrs``.

    Returns
    -------
    xarray.Dataset
        ``NaN`` where a cell has no record or its record no value (see the
        module docstring for ``value_type``).

    Raises
    ------
    ValueError
        A record lacks a dimension, or two records label the same cell.
    """
    import xarray

    dimensions = tuple(dimensions)
    for record in records:
        absent = [name for name in dimensions if name not in record]
        if absent:
            raise ValueError(f"record {record!r} lacks the dimension {absent[0]!r}; every record needs "
                             f"{', '.join(dimensions)}")
    coordinates = {name: _coordinate(records, name) for name in dimensions}
    position = {name: {value: index for index, value in enumerate(values)} for name, values in coordinates.items()}
    shape = tuple(len(values) for values in coordinates.values())
    cells = {}
    for record in records:
        cell = tuple(position[name][record[name]] for name in dimensions)
        if cell in cells:
            labels = ", ".join(f"{name}={record[name]!r}" for name in dimensions)
            raise ValueError(f"two records label the same cell ({labels}); each cell takes one record")
        cells[cell] = record
    names = list(dict.fromkeys(key for record in records for key in record if key not in dimensions))
    variables = {}
    for name in names:
        present = {cell: record[name] for cell, record in cells.items()
                   if name in record and not _missing(record[name])}
        value_type = _value_type(list(present.values())) if present else "real"
        complete = len(present) == math.prod(shape)
        if value_type == "real" or (value_type == "integer" and not complete):
            data = np.full(shape, np.nan)
        elif value_type == "integer":
            data = np.zeros(shape, dtype=np.int64)
        else:
            data = np.full(shape, np.nan, dtype=object)
        for cell, value in present.items():
            data[cell] = bool(value) if value_type == "boolean" else value
        variables[name] = (dimensions, data, {"value_type": value_type})
    return xarray.Dataset(variables, coords=coordinates, attrs=dict(attributes or {}))


def results_dataset(rows, *, attributes=None):
    """A comparison's rows (one per method, spp and seed) as a Dataset with dimensions ``(method, spp, seed)``."""
    return records_dataset(rows, RESULT_DIMENSIONS, attributes=attributes)


def summary_dataset(records, *, attributes=None):
    """The equal-time protocol's records (one per method and spp) as a Dataset with dimensions ``(method, spp)``."""
    return records_dataset(records, SUMMARY_DIMENSIONS, attributes=attributes)


def _text(value, value_type):
    """A cell as the CSV files write it: empty when missing, floats with six significant digits."""
    if _missing(value):
        return ""
    if value_type == "integer":
        return str(int(value))
    if value_type == "boolean":
        return str(bool(value))
    if isinstance(value, (float, np.floating)):
        return f"{value:.6g}"
    return str(value)


def dataset_csv(dataset, columns=None, *, row_order=None):
    """The CSV view of a results Dataset: one row per cell that holds any value.

    Parameters
    ----------
    dataset : xarray.Dataset
        From :func:`records_dataset` (or loaded, :func:`sparselt.load_comparison`).
    columns : sequence of str, optional
        The leading columns, in order (a name the Dataset lacks is an empty
        column); every other variable follows, sorted. Default: the
        dimensions, then the variables in the Dataset's order.
    row_order : sequence of str, optional
        The dimensions from slowest to fastest varying (default the
        Dataset's), each in its coordinate's order.

    Returns
    -------
    str
        CSV text (:mod:`csv` quoting, ``\\n`` line ends); ``''`` for a missing
        value, ``NaN`` included.
    """
    dimensions = tuple(row_order or dataset.dims)
    if set(dimensions) != set(dataset.dims):
        raise ValueError(f"row_order {tuple(row_order)} must name each of the Dataset's dimensions "
                         f"{tuple(dataset.dims)} once")
    variables = list(dataset.data_vars)
    if columns is None:
        header = list(dataset.dims) + variables
    else:
        header = list(columns) + sorted((set(variables) | set(dataset.dims)) - set(columns))
    arrays = {name: dataset[name].transpose(*dimensions).values for name in variables}
    value_types = {name: dataset[name].attrs.get("value_type", "real") for name in variables}
    coordinates = [dataset[name].values for name in dimensions]
    lines = []
    for cell in np.ndindex(*(len(values) for values in coordinates)):
        if all(_missing(arrays[name][cell]) for name in variables):
            continue  # not run
        labels = {name: coordinates[axis][cell[axis]] for axis, name in enumerate(dimensions)}
        texts = [str(labels[name]) if name in labels else
                 _text(arrays[name][cell], value_types[name]) if name in arrays else "" for name in header]
        lines.append((texts[0], texts[1:]))
    return Table(caption="results", label_header=header[0], columns=header[1:], rows=lines).csv()


def read_records_csv(path):
    """A CSV this module wrote (``results.csv``, ``summary.csv``) as typed records: each cell back to the value
    it was written from (``True``/``False`` as booleans, whole numbers as ints, other numbers as floats, text
    as text; an empty cell is ``''``). Six significant digits, as written."""
    import csv

    def value(text):
        if text == "":
            return ""
        if text in ("True", "False"):
            return text == "True"
        try:
            return int(text)
        except ValueError:
            pass
        try:
            return float(text)
        except ValueError:
            return text

    with open(path, newline="", encoding="utf-8") as handle:
        return [{column: value(text) for column, text in row.items()} for row in csv.DictReader(handle)]


__all__ = ["RESULT_DIMENSIONS", "RESULT_ROW_ORDER", "SUMMARY_DIMENSIONS", "VALUE_TYPES", "dataset_csv",
           "read_records_csv", "records_dataset", "results_dataset", "summary_dataset"]
