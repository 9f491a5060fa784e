#!/usr/bin/env python3
"""bench/function_length.py on synthetic C++ sources whose function lengths are known by
construction: braces in comments, strings, raw strings and character literals, digit separators,
lambdas, constructor initialiser lists, classes, namespaces, CUDA attributes, exemption comments,
test files reported apart, file lengths, and the exit status.

    python3 tests/bench/test_function_length.py [--work-dir DIR]
"""
import argparse
import json
import os
import subprocess
import sys
import tempfile

SOURCE = os.path.abspath(os.path.join(os.path.dirname(__file__), "..", ".."))
CHECKER = os.path.join(SOURCE, "bench", "function_length.py")


def body(lines, tricky=""):
    """`lines` lines of statements (the last one holding `tricky`)."""
    out = ["  x += %d;" % i for i in range(lines - 1)]
    out.append("  " + tricky)
    return "\n".join(out)


def function(signature, body_lines, tricky=""):
    """A definition of exactly len(signature lines) + body_lines + 1 lines."""
    return "%s {\n%s\n}\n" % (signature, body(body_lines, tricky))


# name -> (source text, expected length in lines). Each function body is 10 lines unless said.
CASES = []


def case(name, text, length):
    CASES.append((name, text, length))


case("Plain", function("int Plain(int x)", 10), 12)
case("MultiLine", function("static int MultiLine(int x,\n                     int y)", 10), 13)
case("TemplateFn", function("template <typename T, int N = (3 > 2)>\nT TemplateFn(T x)", 10), 13)
case("BraceInComment", function("int BraceInComment(int x)", 10, "x = 1;  // } } {"), 12)
case("BraceInBlockComment", function("int BraceInBlockComment(int x)", 10, "/* }\n } */ x = 1;"), 13)
case("BraceInString", function("const char* BraceInString(int x)", 10, 'return "}}\\"}";'), 12)
case("BraceInRawString", function("const char* BraceInRawString(int x)", 10, 'return R"js(}\n}")js";'), 13)
case("BraceInChar", function("char BraceInChar(int x)", 10, "return x ? '}' : '\\'';"), 12)
case("DigitSeparator", function("int DigitSeparator(int x)", 10, "return 1'000'000 + 0xFF'FF + x;"), 12)
case("WithLambda", function("int WithLambda(int x)", 10, "auto f = [&](int y) { return y + x; }; return f(1);"), 12)
case("Ctor::Ctor", function("Ctor::Ctor(int a)\n    : a_(a), b_{a, 2}, c_(std::vector<int>{1})", 10), 13)
case("Widget::ConstMember", function("int Widget::ConstMember() const noexcept", 10), 12)
case("TrailingReturn", function("auto TrailingReturn(int x) -> decltype(x)", 10), 12)
case("Kernel", function("__global__ void __launch_bounds__(256) Kernel(float* out)", 10), 12)
case("operator==", function("bool operator==(const A& a, const A& b)", 10), 12)
case("TEST(Suite, Name)", function("TEST(Suite, Name)", 10), 12)
case("kLambda", "const auto kLambda = [](int x) {\n%s\n};\n" % body(10), 12)


def source_file():
    """All cases in one file, between declarations, namespaces, a class with inline members,
    an enum, an aggregate initialiser and preprocessor lines that must not be taken for functions."""
    parts = ["#include <vector>", "#define BRACE {", "namespace outer {", "namespace {",
             "enum class E { kA, kB };", "constexpr int kTable[] = {1, 2, 3};", "struct Data { int a; };"]
    for _, text, _ in CASES:
        parts.append(text)
    parts.append("class Holder : public Base<int> {\n public:\n" + function("  int Inline(int x)", 10) + "};")
    parts.append("}  // namespace\n}  // namespace outer")
    return "\n".join(parts) + "\n"


def run(paths, *options):
    result = subprocess.run([sys.executable, CHECKER, "--json", *options, *paths], capture_output=True, text=True)
    if result.returncode not in (0, 1):
        raise SystemExit("function_length.py failed (%d): %s" % (result.returncode, result.stderr))
    return result.returncode, json.loads(result.stdout)


def main():
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--work-dir", help="where to write the synthetic sources (default: a temporary folder)")
    args = parser.parse_args()
    work = args.work_dir or tempfile.mkdtemp(prefix="function_length_")
    os.makedirs(os.path.join(work, "src"), exist_ok=True)
    path = os.path.join(work, "src", "cases.cc")
    with open(path, "w") as f:
        f.write(source_file())
    failures = []

    # --max 1 lists every function with its length.
    rc, report = run([path], "--max", "1")
    found = {fn["name"]: fn["lines"] for fn in report["functions"]}
    expected = {name: length for name, _, length in CASES}
    expected["Inline"] = 12
    for name, length in expected.items():
        if found.get(name) != length:
            failures.append("%s: expected %d lines, found %s" % (name, length, found.get(name)))
    for name in sorted(set(found) - set(expected)):
        failures.append("%s: listed, but it is no function of the file" % name)
    if rc != 1:
        failures.append("exit status %d with functions over the limit (expected 1)" % rc)

    # At the limit nothing is listed; one line less lists the 13-line functions only.
    rc, report = run([path], "--max", "13")
    if report["functions"] or rc != 0:
        failures.append("--max 13: expected nothing and exit 0, got %s (exit %d)" % (report["functions"], rc))
    rc, report = run([path], "--max", "12")
    over = sorted(fn["name"] for fn in report["functions"])
    want = sorted(name for name, length in expected.items() if length > 12)
    if over != want:
        failures.append("--max 12: expected %s, got %s" % (want, over))

    # A stated reason exempts a function; test files are listed apart and never fail the check.
    exempt = os.path.join(work, "src", "exempt.cc")
    with open(exempt, "w") as f:
        f.write("// Does it all.\n// long function: one table, read in order\n" + function("int Long(int x)", 30))
    test_file = os.path.join(work, "src", "long_test.cc")
    with open(test_file, "w") as f:
        f.write(function("TEST(Long, Test)", 30) + "\n".join("// filler" for _ in range(20)) + "\n")
    rc, report = run([exempt, test_file], "--max", "20", "--files", "--file-max", "40")
    if rc != 0 or report["failures"] != 0:
        failures.append("exempt function and test file: expected exit 0, got %d (%s)" % (rc, report))
    if [fn["exemption"] for fn in report["functions"]] != ["one table, read in order"]:
        failures.append("exemption reason: got %s" % report["functions"])
    if [fn["name"] for fn in report["test_functions"]] != ["TEST(Long, Test)"]:
        failures.append("test functions: got %s" % report["test_functions"])
    if [(f["path"], f["lines"]) for f in report["test_files"]] != [(test_file, 52)] or report["files"]:
        failures.append("test files: got %s / %s" % (report["test_files"], report["files"]))

    # A long non-test file fails the check with --files, and only with it.
    rc, report = run([path], "--max", "100", "--files", "--file-max", "100")
    if rc != 1 or [f["path"] for f in report["files"]] != [path]:
        failures.append("long file: expected exit 1 and %s listed, got %d, %s" % (path, rc, report.get("files")))
    rc, report = run([path], "--max", "100")
    if rc != 0:
        failures.append("without --files a long file must not fail the check (exit %d)" % rc)

    for failure in failures:
        print("FAIL:", failure)
    print("%d checks failed" % len(failures) if failures else "all function_length.py checks passed")
    return 1 if failures else 0


if __name__ == "__main__":
    sys.exit(main())
