#!/usr/bin/env bash
# The repository stands on its own (docs/DESIGN.md §19): fast, no build.
#
#   scripts/check-repo.sh
#
# Fails, listing file:line of each finding, if a tracked text file holds
#   - a diary entry: "session N", or an issue number used as an explanation
#     ("issue N");
#   - a path of the machine the project was developed on (the top-level
#     work, home and root folders, the training's /tmp scratch folders);
#   - a reference to a specification outside the repository (shared/DESIGN.md);
#   - "DESIGN.md §N" where docs/DESIGN.md has no section N.
# Prints "check-repo: ok" otherwise. Binary files are skipped.
set -euo pipefail
cd "$(git rev-parse --show-toplevel)"

self=scripts/check-repo.sh
spec=docs/DESIGN.md
# Third-party texts kept verbatim (licences of vendored test suites).
exclude=(":(exclude)$self" ':(exclude)sim-core/tests/compliance/licenses')

failed=0
report() { # title, findings
    if [[ -n "$2" ]]; then
        printf 'check-repo: %s:\n%s\n' "$1" "$2" | cut -c1-200
        failed=1
    fi
}

report 'diary entries ("session N", "issue N")' \
    "$(git grep -n -I -i -E '(^|[^-_A-Za-z])(sessions?|issues?) #?[0-9]+' -- . "${exclude[@]}" || true)"

report 'paths of the development machine' \
    "$(git grep -n -I -E '(^|[^A-Za-z0-9_.~-])/(work|home|root)/|/tmp/(nntrain[0-9]*|nnt|s[0-9]+)/' \
        -- . "${exclude[@]}" || true)"

report 'references to a specification outside the repository' \
    "$(git grep -n -I -E 'shared/DESIGN\.md|DESIGN\.md outside' -- . "${exclude[@]}" || true)"

if [[ ! -f $spec ]]; then
    report 'missing specification' "$spec"
else
    # The sections docs/DESIGN.md has: its "## N." headings.
    sections=" $(sed -n -E 's/^## ([0-9]+)\..*/\1/p' "$spec" | tr '\n' ' ')"
    # Every "DESIGN.md §N", "§N–§M" and "§N-M": each number must be a section.
    bad=$(git grep -n -I -o -E 'DESIGN\.md §[0-9]+([–-]§?[0-9]+)?' -- . "${exclude[@]}" |
        while IFS= read -r hit; do
            for n in $(sed -E 's/^[^§]*//; s/[^0-9]+/ /g' <<<"${hit#*DESIGN.md}"); do
                if [[ $sections != *" $n "* ]]; then
                    printf '%s (no §%s in %s)\n' "$hit" "$n" "$spec"
                fi
            done
        done)
    report "DESIGN.md sections that do not exist" "$bad"
fi

if ((failed)); then
    exit 1
fi
echo "check-repo: ok"
