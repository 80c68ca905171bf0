# Two commands do all the set-up on a fresh machine with Python 3.11:
#   make demo   install sfap and plan the bundled gully survey into out/bardenas-gully
#   make test   install sfap with its test tools and run the whole test suite
PYTHON ?= python3.11
VENV ?= .venv
BIN := $(VENV)/bin

.PHONY: install system-deps demo test test-fast lint bench clean

$(BIN)/sfap: pyproject.toml
	$(PYTHON) -m venv $(VENV)
	$(BIN)/python -m pip install --quiet --upgrade pip
	$(BIN)/python -m pip install --quiet -e ".[dev]"
	# An editable install compiles nothing, and with PYTHONDONTWRITEBYTECODE set every command
	# would compile sfap's modules again at start-up (0.1-0.2 s): compile them once here.
	$(BIN)/python -m compileall -q -j 0 acquisition planner processing sfap
	touch $(BIN)/sfap

install: $(BIN)/sfap

demo: install
	$(BIN)/sfap plan missions/bardenas-gully.toml -o out/bardenas-gully --overwrite

# Debian packages the tests use as independent readers: exiftool (libimage-exiftool-perl).
system-deps:
	@command -v exiftool >/dev/null || { \
	  if [ "$$(id -u)" = 0 ] && command -v apt-get >/dev/null; then \
	    apt-get update -qq && DEBIAN_FRONTEND=noninteractive apt-get install -y -qq libimage-exiftool-perl; \
	  else echo "the tests need exiftool: sudo apt-get install libimage-exiftool-perl" >&2; exit 2; fi; }

# Two pytest-xdist workers: every test binds free ports and writes only its tmp_path.
test: install system-deps
	$(BIN)/python -m pytest -q -n 2

test-fast: install system-deps
	$(BIN)/python -m pytest -q -n 2 -m "not slow"

lint: install
	$(BIN)/ruff check .
	$(BIN)/ruff format --check .
	$(BIN)/mypy

bench: install
	for script in benchmarks/*.py; do echo "== $$script"; $(BIN)/python $$script || exit 1; done

clean:
	rm -rf $(VENV) out build *.egg-info
