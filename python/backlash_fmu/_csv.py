"""CSV cells of the package's tables (the Dask study's and the fleet's)."""


def cell(v):
    """A value as a CSV cell: floats in their shortest form that reads back exactly, None as empty."""
    if v is None:
        return ""
    if isinstance(v, float):
        return repr(v)
    return str(v)
