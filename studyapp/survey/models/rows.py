"""Statements of the answer's path written out once, with the ORM's own conversions.

Every answer reads a trial with its items and their stimuli and writes the items'
answers. Built as querysets, those statements cost more CPU to compile (a
``select_related`` join, a ``bulk_update``'s CASE expressions) than the database takes
to run them (docs/BENCHMARKS.md, "The answer's statements written out and prepared").
Here their SQL is written from the models' metadata once per process and database, and
rows become model instances as the ORM makes them: each column through the converters the
ORM would apply (the backend's and the field's ``from_db_value``), then
``Model.from_db``; values written go through each field's ``get_db_prep_save``. Nothing
here knows a study type.
"""

from __future__ import annotations

from django.conf import settings
from django.db import connection
from django.utils.asyncio import async_unsafe


@async_unsafe
def cursor():
    """Return a cursor for the written-out statements.

    On PostgreSQL (``STUDY_PREPARED_STATEMENTS``, on by default) it binds parameters on the
    server, and psycopg prepares each statement on its connection the first time it runs
    there: the server parses and plans it once per connection rather than once per
    answer (docs/BENCHMARKS.md, "The answer's statements written out and prepared").
    Django's own cursors stay as they are (client-side binding, nothing prepared: what a
    connection pooler in transaction mode needs; turn the setting off behind one that
    does not keep prepared statements: PgBouncer before 1.21, or without
    ``max_prepared_statements``). The cursor is made as Django makes its own (the health
    check, the thread check, the connection's time zone), and a deployment that made
    Django's cursors bind on the server (``OPTIONS["server_side_binding"]``) gets those,
    prepared as it configured. Where queries are logged (``DEBUG``, a test counting
    them) the statements go through Django's cursor, so the log shows them with their
    values."""
    if (connection.vendor != "postgresql" or connection.queries_logged
            or not getattr(settings, "STUDY_PREPARED_STATEMENTS", True)
            or connection.settings_dict.get("OPTIONS", {}).get("server_side_binding")):
        return connection.cursor()
    from django.db.backends.postgresql.base import TIMESTAMPTZ_OID, ServerBindingCursor
    from django.db.backends.postgresql.psycopg_any import register_tzloader
    from psycopg.pq import Format

    connection.close_if_health_check_failed()
    connection.ensure_connection()
    connection.validate_thread_sharing()
    with connection.wrap_database_errors:
        raw = connection.connection
        if raw.prepare_threshold is None:  # Django's default; an OPTIONS setting is kept
            raw.prepare_threshold = 0  # only server-binding cursors prepare: these ones
        server = ServerBindingCursor(raw)
        loader = raw.adapters.get_loader(TIMESTAMPTZ_OID, Format.TEXT)
        if connection.timezone != loader.timezone:  # as Django's create_cursor
            register_tzloader(connection.timezone, server)
    return connection.make_cursor(server)


def quote(name: str) -> str:
    return connection.ops.quote_name(name)


class Columns:
    """The concrete fields of ``model`` (or ``names`` of them, in that order) read under
    the table alias ``alias``; :meth:`build` makes an instance of one row's values."""

    def __init__(self, model, alias: str, names=None):
        self.model, self.alias = model, alias
        fields = model._meta.concrete_fields
        if names is not None:
            by_name = {field.attname: field for field in fields}
            fields = [by_name[name] for name in names]
        self.fields = list(fields)
        self.names = [field.attname for field in self.fields]
        self._converters = {}

    def __len__(self):
        return len(self.fields)

    def sql(self) -> str:
        return ", ".join(f"{self.alias}.{quote(field.column)}" for field in self.fields)

    def converters(self) -> list:
        """``[(index, [converter, ...], column expression)]`` of the columns the ORM
        converts on this connection's backend (as ``SQLCompiler.get_converters``)."""
        key = connection.alias
        if key not in self._converters:
            found = []
            for index, field in enumerate(self.fields):
                column = field.get_col(self.alias)
                functions = (connection.ops.get_db_converters(column)
                             + column.get_db_converters(connection))
                if functions:
                    found.append((index, functions, column))
            self._converters[key] = found
        return self._converters[key]

    def values(self, row) -> list:
        """Return ``row``'s values as the ORM reads them into the fields."""
        values = list(row)
        for index, functions, column in self.converters():
            value = values[index]
            for function in functions:
                value = function(value, column, connection)
            values[index] = value
        return values

    def build(self, row):
        """Return the model instance of ``row`` (this object's columns, in order)."""
        return self.model.from_db(connection.alias, self.names, self.values(row))


class Values:
    """``n`` columns read as they come (counts, ids): :meth:`build` returns them as a tuple."""

    def __init__(self, n: int):
        self.n = n

    def __len__(self):
        return self.n

    def build(self, row) -> tuple:
        return tuple(row)


def prepared(model, name: str, value):
    """Return ``value`` as the database takes it for ``model``'s field ``name``."""
    return model._meta.get_field(name).get_db_prep_save(value, connection)


def read(sql: str, params, *columns: Columns) -> list[tuple]:
    """Run ``sql`` (selecting each of ``columns``' fields in order) and return a tuple of
    instances per row."""
    with cursor() as reading:
        reading.execute(sql, params)
        found = reading.fetchall()
    out = []
    for row in found:
        start, instances = 0, []
        for part in columns:
            instances.append(part.build(row[start:start + len(part)]))
            start += len(part)
        out.append(tuple(instances))
    return out


class Statements:
    """SQL text kept per database connection (vendors quote and lock differently)."""

    every: list = []  # each one made, for tests to know them

    def __init__(self, write):
        self.write, self.kept = write, {}
        Statements.every.append(self)

    def get(self) -> str:
        key = connection.alias, connection.vendor
        if key not in self.kept:
            self.kept[key] = self.write()
        return self.kept[key]
