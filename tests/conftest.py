import pathlib, pytest
SHARED = pathlib.Path(__file__).resolve().parents[1].parent / "shared" / "data"
@pytest.fixture
def shared_data():
    if not SHARED.is_dir():
        pytest.skip("../shared/data not present")
    return SHARED
