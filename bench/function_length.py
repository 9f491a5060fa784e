#!/usr/bin/env python3
"""C++/CUDA functions longer than N lines, and files longer than M lines (Python 3 standard library only).

Usage: function_length.py [--max N] [--files [--file-max M]] [--json] DIR_OR_FILE [...]

The house rule (docs/architecture.md): functions under ~120 lines, files split before ~500 lines.
A function's length is the lines of its whole definition, from the first line of its signature
(template line included) to its closing brace. Functions are found by a brace-matching scan of the
code with comments, string/character literals (raw strings included) and preprocessor lines blanked
out; a brace belongs to a function when what precedes it at namespace or class scope ends like a
signature (a parameter list, then qualifiers, a trailing return type or a constructor's initialiser
list). Lambdas and local classes count as part of the function that holds them; a lambda assigned to
a variable at namespace scope counts as a function of its own. `#if` branches that open braces
differently are beyond this scan (none in this tree).

Exemptions: a function is allowed to be long when the comment right above it (or a comment inside
its signature) contains "long function:" followed by the reason; a file, when one of its first 40
lines holds a comment with "long file:" and the reason.

Test code (a path under a tests/ folder, or a file named *_test.*, *_test_util.*, *_test_*.* or
test_*.*) is listed separately and never changes the exit status: tests may be long.

Exit status: 1 when a function of non-test code is longer than --max without an exemption, or (with
--files) a non-test file is longer than --file-max without one; 0 otherwise; 2 on a usage error.
"""
import argparse
import json
import os
import re
import signal
import sys

CXX_EXTENSIONS = ('.cc', '.cpp', '.cxx', '.c', '.h', '.hh', '.hpp', '.cu', '.cuh')
# Files whose length is checked but whose functions are not (no C++ in them).
OTHER_EXTENSIONS = ('.py',)
SKIPPED_DIRS = {'node_modules', '__pycache__', 'build'}

FUNCTION_EXEMPTION = 'long function:'
FILE_EXEMPTION = 'long file:'
FILE_EXEMPTION_LINES = 40

CONTROL_KEYWORDS = {'if', 'for', 'while', 'switch', 'catch', 'do', 'else', 'try', 'return'}
SCOPE_KEYWORDS = ('namespace', 'class', 'struct', 'union', 'extern')


def is_test_path(path):
    parts = path.replace(os.sep, '/').split('/')
    if 'tests' in parts[:-1]:
        return True
    stem = os.path.splitext(parts[-1])[0]
    return stem.endswith('_test') or '_test_' in stem or stem.startswith('test_')


def blank_non_code(text):
    """The text with comments, literals and preprocessor lines replaced by spaces (newlines kept),
    so that every brace left is a brace of the code and line numbers stay those of the file."""
    out = list(text)
    n = len(text)
    i = 0
    at_line_start = True  # only whitespace so far on this line (for preprocessor directives)

    def blank(a, b):
        for k in range(a, b):
            if out[k] != '\n':
                out[k] = ' '

    while i < n:
        c = text[i]
        if c == '\n':
            at_line_start = True
            i += 1
            continue
        if c in ' \t\r\f\v':
            i += 1
            continue
        if at_line_start and c == '#':
            # A directive runs to the end of the line, continued by a trailing backslash.
            j = i
            while j < n:
                if text[j] == '\n' and text[j - 1] != '\\':
                    break
                if text.startswith('/*', j):  # a block comment may hide the line's end
                    end = text.find('*/', j + 2)
                    j = n if end < 0 else end + 2
                    continue
                j += 1
            blank(i, j)
            i = j
            continue
        at_line_start = False
        if text.startswith('//', i):
            j = text.find('\n', i)
            j = n if j < 0 else j
            blank(i, j)
            i = j
            continue
        if text.startswith('/*', i):
            j = text.find('*/', i + 2)
            j = n if j < 0 else j + 2
            blank(i, j)
            i = j
            continue
        if c == '"':
            # A raw string: R"delim( ... )delim", with an optional u8/u/U/L prefix before the R.
            m = re.search(r'(?:u8|u|U|L)?R$', text[max(0, i - 3):i])
            if m and (i - len(m.group(0)) == 0 or not is_identifier_char(text[i - len(m.group(0)) - 1])):
                open_paren = text.find('(', i + 1)
                delim = text[i + 1:open_paren]
                end = text.find(')' + delim + '"', open_paren)
                j = n if end < 0 else end + len(delim) + 2
                blank(i + 1, j - 1)
                i = j
                continue
            j = skip_quoted(text, i, '"')
            blank(i + 1, j - 1)
            i = j
            continue
        if c == "'":
            if is_digit_separator(text, i):
                i += 1
                continue
            j = skip_quoted(text, i, "'")
            blank(i + 1, j - 1)
            i = j
            continue
        i += 1
    return ''.join(out)


def is_identifier_char(c):
    return c.isalnum() or c == '_'


def is_digit_separator(text, i):
    """Whether the ' at i separates digits (1'000'000, 0xFF'FF) rather than opening a character."""
    j = i
    while j > 0 and (is_identifier_char(text[j - 1]) or text[j - 1] == '.'):
        j -= 1
    return j < i and text[j].isdigit()


def skip_quoted(text, i, quote):
    """The index just past the literal that opens with text[i] == quote (or the line's end when it
    is not closed, so that a stray quote cannot swallow the rest of the file)."""
    j = i + 1
    n = len(text)
    while j < n:
        c = text[j]
        if c == '\\':
            j += 2
            continue
        if c == quote:
            return j + 1
        if c == '\n':
            return j
        j += 1
    return n


def matching_brace(code, open_index):
    depth = 0
    for j in range(open_index, len(code)):
        c = code[j]
        if c == '{':
            depth += 1
        elif c == '}':
            depth -= 1
            if depth == 0:
                return j
    return len(code) - 1


def strip_template_and_attributes(head):
    """The head without leading template<...> clauses, [[attributes]] and access labels."""
    while True:
        head = head.lstrip()
        m = re.match(r'(public|private|protected)\s*:(?!:)', head)
        if m:
            head = head[m.end():]
            continue
        if head.startswith('[['):
            end = head.find(']]')
            head = head[end + 2:] if end >= 0 else ''
            continue
        if re.match(r'template\s*<', head):
            depth = 0
            for j in range(head.index('<'), len(head)):
                if head[j] == '<':
                    depth += 1
                elif head[j] == '>':
                    depth -= 1
                    if depth == 0:
                        head = head[j + 1:]
                        break
            else:
                return head
            continue
        return head


# Words whose parenthesised argument comes before a function's parameter list.
NOT_PARAMETER_LISTS = ('__launch_bounds__', '__attribute__', '__declspec', 'alignas', 'decltype', '__align__')


def top_level_parens(head):
    """(start, end) of each parenthesised group of head at nesting depth 0, but the arguments of
    attribute-like words (__launch_bounds__(256), alignas(16)...) that precede a parameter list."""
    groups = []
    depth = 0
    start = 0
    for j, c in enumerate(head):
        if c == '(':
            if depth == 0:
                start = j
            depth += 1
        elif c == ')':
            depth -= 1
            if depth == 0 and not re.search(r'(%s)\s*$' % '|'.join(NOT_PARAMETER_LISTS), head[:start]):
                groups.append((start, j))
            if depth < 0:
                depth = 0
    return groups


def classify_head(head):
    """What the brace after head opens: 'scope' (namespace, class...: functions inside are listed),
    'function', 'initialiser' (a member's initialiser in a constructor's initialiser list: the scan
    goes on to the body) or 'other' (an enum, an aggregate initialiser...: skipped)."""
    text = strip_template_and_attributes(head)
    first_word = re.match(r'[A-Za-z_]\w*', text)
    first_word = first_word.group(0) if first_word else ''
    if first_word in SCOPE_KEYWORDS:
        return 'scope'
    groups = top_level_parens(text)
    if not groups or first_word in CONTROL_KEYWORDS or first_word in ('enum', 'using', 'typedef'):
        return 'other'
    before_params = text[:groups[0][0]]
    if '=' in re.sub(r'operator\s*[^\s(]*', '', before_params):
        # "auto f = [](...) {...}" is a lambda (a function); "T x = {...}" is data.
        return 'function' if re.search(r'\]\s*$', before_params) else 'other'
    closes = {end for _, end in groups}
    for m in re.finditer(r'\)\s*(?:noexcept\s*)?:(?!:)', text):
        if m.start() in closes and (m.start() == 0 or text[m.start() - 1] != ':'):
            # A constructor's initialiser list "...) : a_(x), b_{": a brace after a member's name (or
            # a template type) opens that member's initialiser; otherwise it opens the body.
            return 'initialiser' if re.search(r'[\w>]\s*$', text) else 'function'
    # What may follow a signature's parameter list before its body.
    tail = text[groups[-1][1] + 1:]
    if re.fullmatch(r'(\s*(const|volatile|noexcept|override|final|mutable|constexpr|&&|&|'
                    r'requires\s.*|->\s*.+))*\s*', tail, re.S):
        return 'function'
    return 'other'


def function_name(head):
    text = strip_template_and_attributes(head)
    m = re.search(r'([\w:~]*operator\s*(?:\(\s*\)|[^\w\s(]+|\s\w[\w:]*))', text)
    if m:
        return re.sub(r'\s+', ' ', m.group(1))
    groups = top_level_parens(text)
    if not groups:
        return text.strip()
    before = text[:groups[0][0]].rstrip()
    lam = re.search(r'(\w+)\s*=\s*\[[^\]]*\]$', before)
    if lam:
        return lam.group(1)
    m = re.search(r'[\w:~]+(?:<[^()]*>)?$', before)
    name = m.group(0) if m else before
    if re.fullmatch(r'[A-Z][A-Z0-9_]*', name):
        # A macro such as TEST(Suite, Name) or PYBIND11_MODULE(...): its arguments name the function.
        name += re.sub(r'\s+', ' ', text[groups[0][0]:groups[0][1] + 1])
    return name


def find_functions(code):
    """(name, head_start, open_brace, close_brace) of each function of the blanked code."""
    functions = []
    scope_stack = [len(code)]  # the closing brace of each enclosing namespace/class scope
    head_start = 0
    function_head = None  # a constructor's head while the scan walks its initialiser list
    i = 0
    n = len(code)
    while i < n:
        c = code[i]
        if c == '}' and i >= scope_stack[-1]:
            scope_stack.pop()
            head_start = i + 1
            i += 1
            continue
        if c == ';':
            head_start = i + 1
            function_head = None
        elif c == '{':
            start = function_head if function_head is not None else head_start
            kind = classify_head(code[start:i])
            if kind == 'scope':
                scope_stack.append(matching_brace(code, i))
                head_start = i + 1
                function_head = None
            elif kind == 'initialiser':
                function_head = start
                i = matching_brace(code, i) + 1
                continue
            else:
                close = matching_brace(code, i)
                if kind == 'function':
                    functions.append((function_name(code[start:i]), start, i, close))
                function_head = None
                i = close + 1
                head_start = i
                # "auto f = [] {...};" and "struct S {...} s;" end at their ';'.
                continue
        i += 1
    return functions


def line_of(line_starts, index):
    lo, hi = 0, len(line_starts) - 1
    while lo < hi:
        mid = (lo + hi + 1) // 2
        if line_starts[mid] <= index:
            lo = mid
        else:
            hi = mid - 1
    return lo + 1


def exemption_reason(lines, first_line, last_head_line, marker):
    """The reason after marker in the comment block right above first_line (1-based) or in the
    lines first_line..last_head_line, or None."""
    candidates = []
    k = first_line - 2
    in_block = False
    while k >= 0:
        stripped = lines[k].strip()
        if in_block or stripped.endswith('*/'):
            candidates.append(lines[k])
            in_block = not (stripped.startswith('/*') or '/*' in stripped)
        elif stripped.startswith('//') or stripped.startswith('*'):
            candidates.append(lines[k])
        else:
            break
        k -= 1
    candidates.extend(lines[first_line - 1:last_head_line])
    for line in candidates:
        pos = line.find(marker)
        if pos >= 0:
            return line[pos + len(marker):].strip(' */') or '(no reason given)'
    return None


def scan_file(path, max_lines):
    with open(path, encoding='utf-8', errors='replace') as f:
        text = f.read()
    lines = text.split('\n')
    line_count = len(lines) - (1 if text.endswith('\n') else 0)
    result = {'path': path, 'lines': line_count, 'functions': []}
    file_reason = None
    for line in lines[:FILE_EXEMPTION_LINES]:
        pos = line.find(FILE_EXEMPTION)
        if pos >= 0:
            file_reason = line[pos + len(FILE_EXEMPTION):].strip(' */#') or '(no reason given)'
    result['file_exemption'] = file_reason
    if not path.endswith(CXX_EXTENSIONS):
        return result
    code = blank_non_code(text)
    line_starts = [0]
    for j, c in enumerate(code):
        if c == '\n':
            line_starts.append(j + 1)
    for name, head_start, open_brace, close_brace in find_functions(code):
        # The signature starts after blanks and access labels ("public:").
        label = re.match(r'(\s|(public|private|protected)\s*:(?!:))*', code[head_start:open_brace])
        first_non_blank = head_start + label.end()
        first = line_of(line_starts, first_non_blank)
        brace_line = line_of(line_starts, open_brace)
        last = line_of(line_starts, close_brace)
        length = last - first + 1
        if length > max_lines:
            result['functions'].append({
                'name': name, 'line': first, 'lines': length,
                'exemption': exemption_reason(lines, first, brace_line, FUNCTION_EXEMPTION)})
    return result


def collect_files(roots):
    files = []
    for root in roots:
        if os.path.isfile(root):
            files.append(root)
            continue
        if not os.path.isdir(root):
            raise SystemExit('function_length.py: %s: no such file or folder' % root)
        for folder, dirs, names in os.walk(root):
            dirs[:] = sorted(d for d in dirs if not d.startswith('.') and d not in SKIPPED_DIRS
                             and not d.startswith('build'))
            for name in sorted(names):
                if name.endswith(CXX_EXTENSIONS + OTHER_EXTENSIONS):
                    files.append(os.path.join(folder, name))
    return files


def main():
    parser = argparse.ArgumentParser(
        description='C++/CUDA functions longer than --max lines (and, with --files, files longer '
                    'than --file-max lines) under the given folders; test code is listed apart and never '
                    'fails the check.')
    parser.add_argument('paths', nargs='+', metavar='DIR_OR_FILE')
    parser.add_argument('--max', type=int, default=120, metavar='N',
                        help='longest function allowed, in lines of its definition (default 120)')
    parser.add_argument('--files', action='store_true',
                        help='also list files longer than --file-max lines')
    parser.add_argument('--file-max', type=int, default=500, metavar='M',
                        help='longest file allowed with --files, in lines (default 500)')
    parser.add_argument('--json', action='store_true', help='one JSON object instead of text')
    args = parser.parse_args()

    functions = {'code': [], 'tests': []}
    files = {'code': [], 'tests': []}
    failures = 0
    for path in collect_files(args.paths):
        scanned = scan_file(path, args.max)
        group = 'tests' if is_test_path(path) else 'code'
        for fn in scanned['functions']:
            fn = dict(fn, path=path)
            functions[group].append(fn)
            if group == 'code' and fn['exemption'] is None:
                failures += 1
        if args.files and scanned['lines'] > args.file_max:
            files[group].append({'path': path, 'lines': scanned['lines'],
                                 'exemption': scanned['file_exemption']})
            if group == 'code' and scanned['file_exemption'] is None:
                failures += 1

    if args.json:
        report = {'max_function_lines': args.max, 'functions': functions['code'],
                  'test_functions': functions['tests'], 'failures': failures}
        if args.files:
            report.update(max_file_lines=args.file_max, files=files['code'], test_files=files['tests'])
        json.dump(report, sys.stdout, indent=1)
        print()
    else:
        print_text(args, functions, files, failures)
    return 1 if failures else 0


def print_text(args, functions, files, failures):
    for group, title in (('code', 'functions'), ('tests', 'test functions (not checked)')):
        print('%d %s over %d lines' % (len(functions[group]), title, args.max))
        for fn in sorted(functions[group], key=lambda f: -f['lines']):
            note = '  [long function: %s]' % fn['exemption'] if fn['exemption'] is not None else ''
            print('  %s:%d: %s: %d lines%s' % (fn['path'], fn['line'], fn['name'], fn['lines'], note))
    if args.files:
        for group, title in (('code', 'files'), ('tests', 'test files (not checked)')):
            print('%d %s over %d lines' % (len(files[group]), title, args.file_max))
            for f in sorted(files[group], key=lambda f: -f['lines']):
                note = '  [long file: %s]' % f['exemption'] if f['exemption'] is not None else ''
                print('  %s: %d lines%s' % (f['path'], f['lines'], note))
    print('%d over the limits without a stated reason' % failures)


if __name__ == '__main__':
    signal.signal(signal.SIGPIPE, signal.SIG_DFL)  # `| head` ends the listing quietly
    sys.exit(main())
