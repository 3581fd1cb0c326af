/* The C header compiles alone as strict C99 (-std=c99 -Wall -Wextra -pedantic
 * -Werror, set in CMakeLists.txt) and links against the shared library: a
 * trivial program that names every status. Exit status 0 when each status
 * has its own non-empty name. */
#include "earshot/earshot.h"

#include <stdio.h>
#include <string.h>

int main(void) {
  const earshot_status all[] = {EARSHOT_OK,
                                EARSHOT_ERROR_INVALID_ARGUMENT,
                                EARSHOT_ERROR_OUT_OF_MEMORY,
                                EARSHOT_ERROR_IO,
                                EARSHOT_ERROR_NOT_FOUND,
                                EARSHOT_ERROR_PARSE,
                                EARSHOT_ERROR_UNSUPPORTED,
                                EARSHOT_ERROR_OUT_OF_RANGE,
                                EARSHOT_ERROR_INVALID_STATE,
                                EARSHOT_ERROR_INTERNAL};
  const size_t n = sizeof(all) / sizeof(all[0]);
  size_t i, j;
  for (i = 0; i < n; ++i) {
    const char* name = earshot_status_string(all[i]);
    if (name == NULL || name[0] == '\0' || strcmp(name, "unknown status") == 0) {
      fprintf(stderr, "status %d has no name\n", (int)all[i]);
      return 1;
    }
    for (j = 0; j < i; ++j) {
      if (strcmp(name, earshot_status_string(all[j])) == 0) {
        fprintf(stderr, "statuses %d and %d share the name \"%s\"\n", (int)all[j], (int)all[i], name);
        return 1;
      }
    }
  }
  if (earshot_version() != EARSHOT_VERSION) {
    fprintf(stderr, "library version %u differs from the header's %u\n", (unsigned)earshot_version(),
            (unsigned)EARSHOT_VERSION);
    return 1;
  }
  printf("%s\n", earshot_status_string(EARSHOT_OK));
  return 0;
}
