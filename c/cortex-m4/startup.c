/* The Cortex-M4F start-up of the example programs (an MPS2 AN386 board, or QEMU's model of
 * it): the vector table, then, on reset, the FPU switched on, .data copied to RAM and .bss
 * zeroed, the command line read through semihosting, main, and exit through semihosting.
 * Newlib's librdimon turns the C library's I/O into semihosting calls to the debugger or to
 * QEMU, so a program reads and writes the host's files and standard output. */
#include <stdint.h>
#include <stdlib.h>
#include <string.h>

extern uint32_t __data_load, __data_start, __data_end, __bss_start, __bss_end, __stack_top;
extern void initialise_monitor_handles(void);
int main(int argc, char **argv);

/* Semihosting's SYS_GET_CMDLINE (0x15): the command line QEMU was given with
 * -semihosting-config ...,arg=..., its arguments joined by spaces. */
static int command_line(char *buffer, int size) {
    struct {
        char *buffer;
        int size;
    } block = {buffer, size - 1};
    register int operation __asm__("r0") = 0x15;
    register void *argument __asm__("r1") = &block;
    __asm__ volatile("bkpt 0xab" : "+r"(operation) : "r"(argument) : "memory");
    if (operation != 0) return -1;
    buffer[block.size] = '\0';
    return 0;
}

/* Run before anything that may use a float register: everything below is compiled with
 * -mfloat-abi=hard, and any floating-point instruction with the FPU off is a UsageFault.
 * Nothing here may touch a float. */
__attribute__((naked, noreturn)) void Reset_Handler(void) {
    __asm__ volatile(
        /* CPACR (0xE000ED88): full access to coprocessors 10 and 11, the FPU */
        "ldr r0, =0xE000ED88\n"
        "ldr r1, [r0]\n"
        "orr r1, r1, #(0xF << 20)\n"
        "str r1, [r0]\n"
        "dsb\n"
        "isb\n" /* the FPU is on for the instructions that follow */
        "b start\n");
}

__attribute__((noreturn, used)) void start(void) {
    memcpy(&__data_start, &__data_load, (char *)&__data_end - (char *)&__data_start);
    memset(&__bss_start, 0, (char *)&__bss_end - (char *)&__bss_start);
    initialise_monitor_handles();
    static char line[512];
    static char *argv[16];
    int argc = 0;
    if (command_line(line, sizeof line) == 0)
        for (char *word = strtok(line, " "); word != NULL && argc < 15; word = strtok(NULL, " "))
            argv[argc++] = word;
    argv[argc] = NULL;
    exit(main(argc, argv)); /* newlib's exit: flush the files, then semihosting's SYS_EXIT */
}

static void halt(void) {
    for (;;) __asm__ volatile("bkpt 0");
}

/* The vector table: the stack's top, then the handlers; a fault stops the program where a
 * debugger (or QEMU's -d int) can see it. */
__attribute__((section(".vectors"), used)) static void (*const vectors[16])(void) = {
    (void (*)(void))&__stack_top, Reset_Handler, halt, halt, halt, halt, halt, 0, 0, 0, 0,
    halt, halt, 0, halt, halt,
};
