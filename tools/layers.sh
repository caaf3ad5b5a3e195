#!/bin/sh
# The core's folders along the data path (Makefile LAYERS, bottom first):
# a file of src/F/ or include/mlip/F/ may include mlip/types.h, mlip/F/ and
# mlip/G/ for a folder G before F in LAYERS, and no other project header
# (rt.h and tools/lib/ are outside the core: -Iinclude alone already refuses
# them); a file of src/F/ may also include a private header of its own
# folder by its bare name ("gc.h" for src/F/gc.h), itself held to F's rules.
# Every violation is named with file, line and the rule; exit 1.
#
#   tools/layers.sh "LAYER..." FILE...
set -u
layers=${1:?usage: layers.sh "LAYER..." FILE...}
shift
bad=0
for f in "$@"; do
	case $f in
	src/*/*) own=${f#src/}; own=${own%%/*} ;;
	include/mlip/*/*) own=${f#include/mlip/}; own=${own%%/*} ;;
	include/mlip/*) own="" ;; # types.h: the base, includes no project header
	*) echo "layers: $f: not in a core folder" >&2; bad=1; continue ;;
	esac
	allowed=""
	if [ -n "$own" ]; then
		found=0
		for l in $layers; do
			allowed="$allowed $l"
			[ "$l" = "$own" ] && { found=1; break; }
		done
		if [ $found = 0 ]; then
			echo "layers: $f: folder '$own' is not in LAYERS ($layers)" >&2
			bad=1
			continue
		fi
	fi
	# every quoted include: mlip/types.h, or mlip/G/... with G allowed
	grep -n '^[[:space:]]*#[[:space:]]*include[[:space:]]*"' "$f" | while IFS= read -r hit; do
		n=${hit%%:*}
		inc=$(printf '%s\n' "$hit" | sed 's/^[^"]*"\([^"]*\)".*/\1/')
		case $inc in
		mlip/types.h) continue ;;
		*/*) ;;
		*)
			# a private header of the file's own folder
			case $f in src/*/*) [ -f "src/$own/$inc" ] && continue ;; esac
			;;
		esac
		case $inc in
		mlip/*/*)
			g=${inc#mlip/}; g=${g%%/*}
			case " $allowed " in *" $g "*) continue ;; esac
			echo "$f:$n: includes $inc: folder '${own:-include/mlip}' may include only" \
				"mlip/types.h and mlip/{${allowed# }}/ (Makefile LAYERS, bottom first: $layers)" >&2
			;;
		*)
			echo "$f:$n: includes \"$inc\": the core includes project headers as mlip/FOLDER/NAME.h only" \
				"(or a private header of its own src/ folder by its name)" >&2
			;;
		esac
		echo bad
	done | grep -q bad && bad=1
done
exit $bad
