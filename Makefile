# The two commands of the README. Both work on a fresh machine: they make a
# virtual environment in .venv, build the Rust extension with maturin (through
# pip) and install the package with what it needs from PyPI.
VENV ?= .venv
PY := $(VENV)/bin/python

.PHONY: demo test test-fast wheel docs bench report

$(PY):
	python3 -m venv $(VENV)
	$(PY) -m pip install -q --upgrade pip

# Solve the demo robot (softspine-demo.png), then track the seed's circle with
# 30 g at the tip by load-aware inverse kinematics (softspine-track.png).
demo: $(PY)
	$(PY) -m pip install -q ".[plot]"
	$(PY) -m softspine demo --out softspine-demo.png
	$(PY) -m softspine track --trajectory circle --load 0.03 --out softspine-track.png

# Every test: lint (ruff, rustfmt, clippy), the stubs against the extension
# (stubtest), mypy, pytest (Python API, references, bad input, hard cases,
# properties, the README's and the examples' code), cargo test and the docs
# (--strict, not --quiet: --quiet hides the warnings that --strict counts).
# pytest runs a module a worker on every core (the SciPy references of the
# tendon tests alone take three minutes of one core).
test: $(PY)
	$(PY) -m pip install -q ".[test,docs]"
	$(PY) -m ruff check python tests tools
	$(PY) -m mypy.stubtest softspine._core
	$(PY) -m mypy python/softspine examples
	cargo fmt --all -- --check
	cargo clippy --all-targets --features python -- -D warnings
	$(PY) -m pytest -q -n auto --dist loadfile
	cargo test
	NO_MKDOCS_2_WARNING=1 $(PY) -m mkdocs build --strict -d site

# A wheel to copy to another machine of the same platform (Linux x86-64
# here; Python >= 3.10, one wheel for every version: abi3) in dist/:
# pip install dist/softspine-*.whl there, no Rust needed.
wheel: $(PY)
	$(PY) -m pip wheel --no-deps -w dist .

# The tests a change usually needs, in a few minutes: pytest without the
# slow ones (the references' convergence studies, the examples, clusters,
# Ctrl-C probes: marked slow), after ruff. make test runs everything.
test-fast: $(PY)
	$(PY) -m pip install -q ".[test]"
	$(PY) -m ruff check python tests tools
	$(PY) -m pytest -q -n auto --dist loadfile -m "not slow"

# The documentation site (site/): guide, conventions, the model, the examples
# gallery (from examples/) and the API reference (mkdocstrings), --strict.
docs: $(PY)
	$(PY) -m pip install -q ".[docs]"
	NO_MKDOCS_2_WARNING=1 $(PY) -m mkdocs build --strict -d site

# Speed against error of every method (docs/report.*, the table of docs/reference.md); a
# development tool: the references it compares with are in tools/validation.
report: $(PY)
	$(PY) -m pip install -q ".[test]"
	$(PY) tools/report.py --out docs --readme docs/reference.md

# Criterion benchmarks (medians in docs/reference.md): forward statics, time to
# accuracy of every scheme and method, IK, the paper.
bench:
	cargo bench --bench forward
	cargo bench --bench accuracy
	cargo bench --bench robot
	cargo bench --bench paper
	cargo bench --bench contact
