"""What every test module shares: the job stores of the acceptance battery, the reproduction
and the tuning (emasim.experiments.store.keyed, under runs/ of the working folder by default)
go into a temporary folder of the module's own, module fixtures included, so that no test
writes into the working tree and no module resumes another's runs."""

import pytest

from emasim import tuning
from emasim.experiments import acceptance, reproduction


@pytest.fixture(scope="module", autouse=True)
def stores_in_tmp(tmp_path_factory):
    root = tmp_path_factory.mktemp("stores")
    with pytest.MonkeyPatch.context() as patch:
        patch.setattr(acceptance, "STORE_ROOT", root / "acceptance")
        patch.setattr(reproduction, "STORE_ROOT", root / "reproduce")
        patch.setattr(tuning, "STORE_ROOT", root / "tune")
        yield root
