import orthospec


def test_all_is_sorted_and_complete():
    assert orthospec.__all__ == sorted(orthospec.__all__)
    import __future__

    public = {n for n in dir(orthospec) if not n.startswith("_")
              and not isinstance(getattr(orthospec, n), type(orthospec) | __future__._Feature)}
    assert public | {"__version__"} == set(orthospec.__all__)


def test_errors_share_one_root():
    for name in orthospec.__all__:
        obj = getattr(orthospec, name)
        if isinstance(obj, type) and issubclass(obj, Exception):
            assert issubclass(obj, orthospec.OrthospecError)
