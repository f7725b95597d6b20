#!/usr/bin/env bash
# No function of the product is longer than a reader can hold: the tree has none over 150
# lines, and the counter finds one it is shown (so the check cannot pass by counting nothing).
set -uo pipefail
src=$1
count="$src/scripts/function-lengths.py"
tmp=$(mktemp -d); trap 'rm -rf "$tmp"' EXIT
pass=0 fail=0
ok() { pass=$((pass + 1)); echo "ok   $1"; }
bad() { fail=$((fail + 1)); echo "FAIL $1"; }

if out=$(python3 "$count" "$src" --over 150 --fail-over 150); then
  ok "the source tree: no function over 150 lines"
else
  bad "the source tree has functions over 150 lines:"; echo "$out"
fi

# A made-up tree: one 160-line function (with braces in strings, comments and a lambda inside,
# none of which may end it early), one 20-line function and a class with a long method.
mkdir -p "$tmp/process/x"
{
  echo 'namespace rig {'
  echo 'int Long(int a) {'
  echo '  auto f = [&](int b) { return b + 1; };  // } a brace in a comment'
  echo '  const char* s = "}}}";'
  for i in $(seq 1 155); do echo "  a += f($i);"; done
  echo '  return a;'
  echo '}'
  echo 'int Short() {'
  for i in $(seq 1 18); do echo "  int v$i = $i;"; done
  echo '}'
  echo 'struct S {'
  echo '  int Method() const {'
  for i in $(seq 1 120); do echo "    int w$i = $i;"; done
  echo '    return 0;'
  echo '  }'
  echo '};'
  echo '}  // namespace rig'
} > "$tmp/process/x/long.cc"
out=$(python3 "$count" "$tmp" --over 100 --fail-over 150); rc=$?
if [ "$rc" -eq 1 ] && grep -qE '^ +160 +process/x/long.cc:2 +Long$' <<<"$out" &&
   grep -qE '^ +123 +process/x/long.cc:.* +Method$' <<<"$out" && ! grep -q ' Short$' <<<"$out"; then
  ok "a made-up tree: the 160-line function found and failed, the method counted, the short one not listed"
else
  bad "a made-up tree (exit $rc):"; echo "$out"
fi

echo "$pass passed, $fail failed"
[ "$fail" -eq 0 ]
