"""A TOML file's text with new values laid over it, its comments and layout kept (tomlkit):
what ``emasim tune`` writes back into a scenario and ``emasim identify`` calibrates."""


def laid_over(original: str, values: dict) -> str:
    """The text ``original`` made to hold the table ``values``: every item whose value is
    unchanged keeps its place and comments, tables and arrays of tables of the same length
    are entered, other values replaced, keys ``values`` lacks removed."""
    import tomlkit

    document = tomlkit.parse(original)
    _lay_over(document, values)
    return tomlkit.dumps(document)


def _lay_over(table, values: dict) -> None:
    for key in [k for k in table if k not in values]:
        del table[key]
    for key, value in values.items():
        old = table.get(key)
        if isinstance(value, dict) and isinstance(old, dict):
            _lay_over(old, value)
        elif _tables(value) and _tables(old) and len(old) == len(value):
            for item, new in zip(old, value, strict=True):
                _lay_over(item, new)
        elif old is None or _plain(old) != value:
            table[key] = value


def _tables(value) -> bool:
    return isinstance(value, list) and bool(value) and all(isinstance(v, dict) for v in value)


def _plain(value):
    """A tomlkit item as plain Python data."""
    return value.unwrap() if hasattr(value, "unwrap") else value
