"""CI (.ci/run sets CI=1) runs hypothesis derandomised, so a green run is reproducible; locally it explores new
examples."""

import os

from hypothesis import settings

settings.register_profile("ci", derandomize=True, deadline=None)
settings.register_profile("dev", deadline=None)
settings.load_profile("ci" if os.environ.get("CI") else "dev")
