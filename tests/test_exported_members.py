import orthospec


def test_all_is_sorted_and_complete():
    assert orthospec.__all__ == sorted(orthospec.__all__)
    import __future__

    public = {n for n in dir(orthospec) if not n.startswith("_")
              and not isinstance(getattr(orthospec, n), type(orthospec) | __future__._Feature)}
    assert all(getattr(orthospec, n) is not None for n in orthospec.__all__)
    assert public | {"__version__"} == set(orthospec.__all__)


def test_errors_share_one_root():
    for name in orthospec.__all__:
        obj = getattr(orthospec, name)
        if isinstance(obj, type) and issubclass(obj, Exception):
            assert issubclass(obj, orthospec.OrthospecError)


def test_importing_the_raster_layer_does_not_load_the_engine():
    import subprocess
    import sys

    code = (
        "import sys, orthospec.raster.reading; "
        "print(any(m.startswith(('orthospec.api', 'orthospec.engine', 'pydantic')) for m in sys.modules))"
    )
    out = subprocess.run(
        [sys.executable, "-c", code], capture_output=True, text=True, check=True
    ).stdout
    assert out.strip() == "False"
