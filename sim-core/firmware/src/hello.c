/* The smallest semihosting program: one line on the console, exit 0. */
#include <stdio.h>

int main(void)
{
    printf("Hello from the RV32IMC ISS!\n");
    return 0;
}
