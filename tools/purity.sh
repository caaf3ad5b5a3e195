#!/bin/sh
# make purity: the core (libmlip.a, src/) is pure - libm and the pure string
# functions, no I/O, no allocation, no system calls - so the simulator, the
# checker and the real-time loop run the same code, and nothing in it can
# block or fail at run time. Every undefined symbol of the archive that no
# member of it defines must be on the allow-list below; anything else (printf,
# malloc, clock_gettime, pthread_*, ...) is named and fails the build.
set -e
lib=${1:?usage: purity.sh BUILD/libmlip.a}
NM=${NM:-nm}
allow='
acos acosh asin atan atan2 cbrt ceil copysign cos cosh exp exp2 expm1 fabs floor
fma fmax fmin fmod frexp hypot ldexp llrint llround log log10 log1p log2 lrint
lround modf nearbyint nextafter pow remainder rint round scalbn sin sincos sinh
sqrt tan tanh trunc
memchr memcmp memcpy memmove memset strchr strcmp strlen strncmp strncpy strrchr
__stack_chk_fail
'
undef=$($NM -u "$lib" | awk 'NF == 2 && $1 == "U" { print $2 }' | sort -u)
def=$($NM --defined-only "$lib" | awk 'NF == 3 { print $3 }' | sort -u)
bad=""
for s in $undef; do
	case " $(echo $def) " in *" $s "*) continue ;; esac
	case " $(echo $allow) " in *" $s "*) continue ;; esac
	case $s in __asan_* | __ubsan_* | __tsan_* | __sanitizer_* | __lsan_*) continue ;; esac # make asan/ubsan/tsan
	bad="$bad $s"
done
if [ -n "$bad" ]; then
	echo "purity: $lib uses what the pure core must not (libm and string functions only):" >&2
	for s in $bad; do
		where=$($NM -A -u "$lib" 2>/dev/null | awk -v s="$s" '$NF == s { split($1, p, ":"); print p[2] }' | sort -u | tr '\n' ' ')
		echo "  $s  (in $where)" >&2
	done
	exit 1
fi
n=$(echo "$undef" | grep -c . || true)
echo "purity: $lib: $n external symbols, all libm or pure string functions"
